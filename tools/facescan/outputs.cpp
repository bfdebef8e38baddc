#include "facescan/outputs.hpp"

#include <dirent.h>
#include <sys/stat.h>

#include <cctype>
#include <cstdlib>
#include <cstring>

namespace facescan::cli {

namespace {

bool ends_with(const std::string &s, const std::string &suffix)
{
	return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Where a path's directory entry lives: the real path of its directory plus its own name. A
// rename onto the path replaces exactly that entry (a symlink there is replaced, not followed).
bool entry_of(const std::string &path, std::string *ret)
{
	const size_t slash = path.find_last_of('/');
	const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
	const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
	if (name.empty() || name == "." || name == "..")
		return false;
	char *real = realpath(dir.c_str(), nullptr);
	if (!real)
		return false;
	*ret = std::string(real) + (std::strcmp(real, "/") == 0 ? "" : "/") + name;
	std::free(real);
	return true;
}

// Whether `name` is one of a capture set's own files (docs/capture-format.md).
bool is_capture_file(const std::string &name)
{
	if (name == "calibration.yaml" || name == "capture.json" || name == "ground_truth.ply" ||
	    name == "ground_truth_projectors.yaml" || name == "ground_truth_face.ply")
		return true;
	size_t i = 3;
	if (name.compare(0, 3, "cam") != 0 || name.size() <= i || !std::isdigit((unsigned char)name[i]))
		return false;
	while (i < name.size() && std::isdigit((unsigned char)name[i]))
		i++;
	const std::string rest = name.substr(i);
	return rest == ".png" || rest == "_texture.png";
}

std::vector<InputFile> entries_of(const std::string &dir, bool capture_files_only, const std::string &role)
{
	std::vector<InputFile> inputs;
	if (DIR *d = opendir(dir.c_str())) {
		while (dirent *e = readdir(d)) {
			const std::string name = e->d_name;
			if (name == "." || name == ".." || (capture_files_only && !is_capture_file(name)))
				continue;
			inputs.push_back({dir + "/" + name, role});
		}
		closedir(d);
	}
	return inputs;
}

} // namespace

std::vector<InputFile> capture_set_inputs(const std::string &dir)
{
	return entries_of(dir, true, "an input of the capture set");
}

std::vector<InputFile> directory_inputs(const std::string &dir, const std::string &role)
{
	return entries_of(dir, false, role);
}

bool check_outputs(const std::vector<InputFile> &inputs,
		   const std::vector<std::pair<std::string, const char *>> &outputs, std::string *ret_why)
{
	struct Input {
		std::string entry, target, role;
		dev_t dev = 0;
		ino_t ino = 0;
	};
	std::vector<Input> known;
	for (const InputFile &file : inputs) {
		Input in;
		in.role = file.role;
		if (!entry_of(file.path, &in.entry))
			continue;
		if (char *t = realpath(file.path.c_str(), nullptr)) {
			in.target = t;
			std::free(t);
		}
		struct stat st;
		if (stat(file.path.c_str(), &st) == 0) {
			in.dev = st.st_dev;
			in.ino = st.st_ino;
		}
		known.push_back(in);
	}
	std::vector<std::string> seen;
	for (const auto &[path, ext] : outputs) {
		if (path.empty())
			continue; // not asked for
		if (!ends_with(path, ext) || path.size() == std::strlen(ext) || ends_with(path, std::string("/") + ext)) {
			*ret_why = path + ": must be a file name" + (*ext ? std::string(" ending in ") + ext : "");
			return false;
		}
		std::string entry;
		if (!entry_of(path, &entry)) {
			*ret_why = path + ": its directory does not exist";
			return false;
		}
		struct stat st;
		const bool exists = stat(path.c_str(), &st) == 0;
		if (exists && !S_ISREG(st.st_mode)) {
			*ret_why = path + ": exists and is not a regular file";
			return false;
		}
		for (const Input &in : known)
			if (entry == in.entry || entry == in.target ||
			    (exists && st.st_dev == in.dev && st.st_ino == in.ino)) {
				*ret_why = path + ": is " + in.role + " (" + in.entry + "); choose another name";
				return false;
			}
		for (const std::string &other : seen)
			if (entry == other) {
				*ret_why = path + ": names the same file as another output";
				return false;
			}
		seen.push_back(entry);
	}
	return true;
}

} // namespace facescan::cli
