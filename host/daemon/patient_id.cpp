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
	// Windows and SMB (which clinics' shares are) cannot hold a folder named after a device,
	// with or without an extension ("aux.txt"), nor one ending in a dot.
	if (id.back() == '.')
		return Status::error(EINVAL, "patient id ends with '.' (not a valid folder on Windows shares)");
	std::string stem = id.substr(0, id.find('.'));
	for (char &ch : stem)
		if (ch >= 'a' && ch <= 'z')
			ch = static_cast<char>(ch - 'a' + 'A');
	static const char *const kReserved[] = {"CON", "PRN", "AUX", "NUL"};
	bool reserved = false;
	for (const char *r : kReserved)
		reserved = reserved || stem == r;
	if (stem.size() == 4 && (stem.compare(0, 3, "COM") == 0 || stem.compare(0, 3, "LPT") == 0) &&
	    stem[3] >= '0' && stem[3] <= '9')
		reserved = true;
	if (reserved)
		return Status::error(EINVAL, "patient id is a reserved device name on Windows shares (CON, PRN, "
					     "AUX, NUL, COM0-9, LPT0-9)");
	return Status();
}

} // namespace facescan::daemon
