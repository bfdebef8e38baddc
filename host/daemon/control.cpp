#include "daemon/control.hpp"
#include "dicom/dicom.hpp"

#include <nlohmann/json.hpp>

namespace facescan::daemon {

LineReader::Result LineReader::next(std::string *ret_line)
{
	if (poisoned_)
		return Result::too_large;
	size_t nl = buf_.find('\n');
	if (nl == std::string::npos) {
		if (buf_.size() >= kMaxRequest) {
			poisoned_ = true;
			buf_.clear();
			return Result::too_large;
		}
		return Result::need_more;
	}
	if (nl + 1 > kMaxRequest) {
		poisoned_ = true;
		buf_.clear();
		return Result::too_large;
	}
	ret_line->assign(buf_, 0, nl);
	buf_.erase(0, nl + 1);
	if (!ret_line->empty() && ret_line->back() == '\r')
		ret_line->pop_back();
	return Result::line;
}

Status parse_request(const std::string &line, Request *ret_request)
{
	nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
	if (j.is_discarded())
		return Status::error(EINVAL, "request is not valid JSON");
	if (!j.is_object())
		return Status::error(EINVAL, "request is not a JSON object");
	if (!j.contains("cmd") || !j["cmd"].is_string())
		return Status::error(EINVAL, "request has no \"cmd\" string");
	Request r;
	const std::string cmd = j["cmd"];
	if (cmd == "scan")
		r.cmd = Request::Cmd::scan;
	else if (cmd == "status")
		r.cmd = Request::Cmd::status;
	else if (cmd == "last")
		r.cmd = Request::Cmd::last;
	else if (cmd == "cancel")
		r.cmd = Request::Cmd::cancel;
	else if (cmd == "button")
		r.cmd = Request::Cmd::button;
	else
		return Status::error(EINVAL, "unknown cmd (scan, status, last, cancel, button)");
	for (auto it = j.begin(); it != j.end(); ++it) {
		const std::string &k = it.key();
		if (k == "cmd")
			continue;
		if (r.cmd == Request::Cmd::scan && k == "patient") {
			if (!it->is_string())
				return Status::error(EINVAL, "\"patient\" must be a string");
			r.patient = it->get<std::string>();
		} else if (r.cmd == Request::Cmd::scan && (k == "name" || k == "accession" || k == "study_uid")) {
			if (!it->is_string())
				return Status::error(EINVAL, "\"" + k + "\" must be a string");
			const std::string v = it->get<std::string>();
			Status s = k == "name" ? dicom::validate_patient_name(v)
				   : k == "accession" ? dicom::validate_accession(v)
						      : dicom::validate_uid(v);
			if (!s.ok())
				return s;
			(k == "name" ? r.name : k == "accession" ? r.accession : r.study_uid) = v;
		} else if (r.cmd == Request::Cmd::scan && k == "wait") {
			if (!it->is_boolean())
				return Status::error(EINVAL, "\"wait\" must be true or false");
			r.wait = it->get<bool>();
		} else {
			return Status::error(EINVAL, "unknown field \"" + k + "\" for cmd " + cmd);
		}
	}
	if (r.cmd == Request::Cmd::scan && !j.contains("patient"))
		return Status::error(EINVAL, "scan needs \"patient\"");
	*ret_request = r;
	return Status();
}

} // namespace facescan::daemon
