// The control socket's protocol: one JSON object per line (UTF-8, '\n'-terminated, at most
// kMaxRequest bytes with the newline). Requests:
//   {"cmd":"scan","patient":"ID"[,"wait":true]}   start (clinic) or arm (booth) a scan
//   {"cmd":"status"}   {"cmd":"last"}   {"cmd":"cancel"}   {"cmd":"button"}
// Every reply is one JSON line with "ok": true/false; a refusal has "error" (a short code:
// busy, unavailable, bad_request, too_large, bad_patient_id, unsupported) and "message".
// With "wait", progress lines {"event":"progress",...} follow, then {"event":"done",...}.
#pragma once

#include "common/status.hpp"

#include <string>

namespace facescan::daemon {

constexpr size_t kMaxRequest = 4096;

/// Splits a byte stream into lines. A line longer than kMaxRequest is an error that poisons the
/// reader (the connection is then closed: resynchronising inside a huge line is not worth it).
class LineReader {
public:
	enum class Result { need_more, line, too_large };
	void feed(const char *data, size_t n)
	{
		buf_.append(data, n);
	}
	/// Takes the next complete line (without the '\n') into *ret_line.
	Result next(std::string *ret_line);

private:
	std::string buf_;
	bool poisoned_ = false;
};

struct Request {
	enum class Cmd { scan, status, last, cancel, button } cmd = Cmd::status;
	std::string patient;
	bool wait = false;
	// DICOM fields of a scan request (host/dicom's rules); empty: not given.
	std::string name, accession, study_uid;
};

/// Parses one request line. -EINVAL with a message for malformed JSON, a non-object, an unknown
/// or missing "cmd", wrong field types, or unknown fields, and for a scan's "name", "accession"
/// and "study_uid" that break DICOM's rules (dicom::validate_*). The patient id is checked
/// separately.
Status parse_request(const std::string &line, Request *ret_request);

} // namespace facescan::daemon
