// The clinic's files of a scan, beside the .drc/.png/.json the spool delivers: .glb, the
// thumbnail, .stl/.obj when configured, the DICOM instance (to the share and/or the PACS), and
// the metadata's manifest of every file with its size and sha256. Kept apart from daemon.cpp,
// which calls it at two points: when a scan's files are assembled, and when the spool is retried.
#pragma once

#include "daemon/backends.hpp"
#include "daemon/config.hpp"
#include "daemon/spool.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace facescan::daemon::clinic {

/// Hex SHA-256 of bytes (OpenSSL).
std::string sha256_hex(const std::string &bytes);

/// Adds the configured outputs of a scan to `files` (named <base>.<ext>) and records them in
/// `meta`: "manifest" lists every file of the scan but the metadata itself (name, role, bytes,
/// sha256); "dicom" says where the instance's copies are (the share, the PACS or the DICOM spool).
/// `rec` is the scan's record (patient_id, base, and the request's dicom_name / dicom_accession /
/// dicom_study_uid when given). Sends to the PACS once (bounded by pacs_timeout_s); when it
/// does not answer the instance waits in <spool_dir>/dicom for retry_pacs(). A failure of an
/// optional output is reported in `meta["output_errors"]` and does not lose the scan.
void add_outputs(const Config &cfg, const ReconOutput &out, const nlohmann::json &rec,
		 std::vector<SpoolFile> *files, nlohmann::json *meta);

/// True when instances wait in the DICOM spool for a configured PACS.
bool pacs_pending(const Config &cfg);
/// Sends what waits, in order; for each instance sent, the scan's metadata on the share (when it
/// is there) is rewritten atomically to say so. Returns the first failure, or 0.
Status retry_pacs(const Config &cfg);

} // namespace facescan::daemon::clinic
