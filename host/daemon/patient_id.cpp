#include "daemon/patient_id.hpp"

namespace facescan::daemon {

Status validate_patient_id(const std::string &id)
{
	if (id.empty())
		return Status::error(EINVAL, "patient id is empty");
	if (id.size() > kPatientIdMax)
		return Status::error(EINVAL, "patient id longer than " + std::to_string(kPatientIdMax) +
						     " characters");
	for (char ch : id) {
		unsigned char u = static_cast<unsigned char>(ch);
		if (ch == '/' || ch == '\\')
			return Status::error(EINVAL, "patient id contains a path separator");
		if (u < 0x20 || u == 0x7f)
			return Status::error(EINVAL, "patient id contains a control character");
	}
	if (id.find("..") != std::string::npos)
		return Status::error(EINVAL, "patient id contains '..'");
	if (id[0] == '.')
		return Status::error(EINVAL, "patient id starts with '.'");
	for (char ch : id) {
		bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
			  ch == '.' || ch == '_' || ch == '-';
		if (!ok)
			return Status::error(EINVAL, "patient id may only contain letters, digits, '.', '_' "
						     "and '-'");
	}
	return Status();
}

} // namespace facescan::daemon
