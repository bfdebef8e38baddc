// What the CLI's verbs write must never replace what they read, nor each other (issue 12:
// `facescan recon -o CAP/cam0.drc` once overwrote its own frame). One check for every verb.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace facescan::cli {

/// A file a verb reads, and how the refusal names it ("an input of the capture set").
struct InputFile {
	std::string path, role;
};

/// A capture set's own files in `dir` (docs/capture-format.md: frames, calibration, metadata,
/// ground truth), each with the role "an input of the capture set".
std::vector<InputFile> capture_set_inputs(const std::string &dir);

/// Every entry directly inside `dir` (a directory a verb reads whole), with `role`.
std::vector<InputFile> directory_inputs(const std::string &dir, const std::string &role);

/// Refuses outputs (path, required extension; "" = any; an empty path is an output not asked
/// for and is skipped) that would replace an input or each other: each must end in its extension, be in a directory that exists, not be a non-regular file, and be
/// neither an input (by its directory entry, by where an input's symlink points, or by inode)
/// nor another output. False with the reason in *ret_why.
bool check_outputs(const std::vector<InputFile> &inputs,
		   const std::vector<std::pair<std::string, const char *>> &outputs, std::string *ret_why);

} // namespace facescan::cli
