// C-STORE to the PACS (DCMTK's DcmSCU) and the DICOM spool that holds instances until it answers.
#include "dicom/dicom.hpp"

#include "capture/capture_set.hpp"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmnet/scu.h>
#include <dcmtk/oflog/oflog.h>

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <mutex>

namespace facescan::dicom {

namespace {

void quiet_dcmtk()
{
	static std::once_flag once;
	std::call_once(once, [] { OFLog::configure(OFLogger::OFF_LOG_LEVEL); });
}

Status validate_ae(const std::string &ae, const char *what)
{
	if (ae.empty() || ae.size() > 16)
		return Status::error(-EINVAL, std::string(what) + ": AE title must be 1..16 characters");
	for (char ch : ae) {
		const unsigned char u = static_cast<unsigned char>(ch);
		if (u < 0x20 || u >= 0x7f || ch == '\\')
			return Status::error(-EINVAL, std::string(what) + ": AE title may only hold printable ASCII "
									 "without '\\'");
	}
	return {};
}

bool is_spool_name(const std::string &n)
{
	return n.size() > 15 && n[10] == '_' && n.compare(n.size() - 4, 4, ".dcm") == 0 &&
	       std::all_of(n.begin(), n.begin() + 10, [](char c) { return c >= '0' && c <= '9'; });
}

} // namespace

Status validate_pacs(const Pacs &pacs)
{
	Status s = validate_ae(pacs.calling_ae, "calling AE");
	if (s.ok())
		s = validate_ae(pacs.called_ae, "called AE");
	if (!s.ok())
		return s;
	if (pacs.host.empty())
		return Status::error(-EINVAL, "PACS host is empty");
	if (pacs.port < 1 || pacs.port > 65535)
		return Status::error(-EINVAL, "PACS port outside 1..65535");
	if (pacs.timeout_s < 1)
		return Status::error(-EINVAL, "PACS timeout must be >= 1 s");
	return {};
}

Status c_store(const Pacs &pacs, const std::string &path)
{
	quiet_dcmtk();
	Status s = validate_pacs(pacs);
	if (!s.ok())
		return s;
	if (access(path.c_str(), R_OK) != 0)
		return Status::error(-ENOENT, path + ": cannot read");
	const std::string where = pacs.called_ae + "@" + pacs.host + ":" + std::to_string(pacs.port);
	DcmSCU scu;
	scu.setAETitle(pacs.calling_ae.c_str());
	scu.setPeerAETitle(pacs.called_ae.c_str());
	scu.setPeerHostName(pacs.host.c_str());
	scu.setPeerPort(Uint16(pacs.port));
	scu.setConnectionTimeout(pacs.timeout_s);
	scu.setACSETimeout(Uint32(pacs.timeout_s));
	scu.setDIMSETimeout(Uint32(pacs.timeout_s));
	scu.setDIMSEBlockingMode(DIMSE_NONBLOCKING); // so the DIMSE timeout holds
	OFList<OFString> xfers;
	xfers.push_back(UID_LittleEndianExplicitTransferSyntax);
	xfers.push_back(UID_LittleEndianImplicitTransferSyntax);
	scu.addPresentationContext(UID_EncapsulatedSTLStorage, xfers);
	OFCondition c = scu.initNetwork();
	if (c.bad())
		return Status::error(-EIO, "DICOM network: " + std::string(c.text()));
	c = scu.negotiateAssociation();
	if (c.bad())
		return Status::error(-ECONNREFUSED, where + ": no association: " + c.text());
	const T_ASC_PresentationContextID pc = scu.findPresentationContextID(UID_EncapsulatedSTLStorage, "");
	if (pc == 0) {
		scu.releaseAssociation();
		return Status::error(-EPROTO, where + ": does not accept Encapsulated STL");
	}
	Uint16 status = 0xFFFF;
	c = scu.sendSTORERequest(pc, path.c_str(), nullptr, status);
	if (c.bad()) {
		scu.abortAssociation();
		return Status::error(-ETIMEDOUT, where + ": C-STORE: " + c.text());
	}
	scu.releaseAssociation();
	// 0x0000 success; 0xB000/0xB007/0xB006 are warnings (stored, coerced or elements discarded).
	if (status != 0x0000 && (status & 0xF000) != 0xB000) {
		char hex[8];
		std::snprintf(hex, sizeof hex, "%04X", status);
		return Status::error(-EPROTO, where + ": refused the instance, status 0x" + hex);
	}
	return {};
}

Status Outbox::open()
{
	if (mkdir(dir_.c_str(), 0750) < 0 && errno != EEXIST)
		return Status::error(-errno, dir_ + ": cannot create: " + std::strerror(errno));
	struct stat st;
	if (stat(dir_.c_str(), &st) < 0 || !S_ISDIR(st.st_mode))
		return Status::error(-ENOTDIR, dir_ + ": not a directory");
	return {};
}

std::vector<std::string> Outbox::pending() const
{
	std::vector<std::string> names;
	if (DIR *d = opendir(dir_.c_str())) {
		while (dirent *e = readdir(d))
			if (is_spool_name(e->d_name))
				names.emplace_back(e->d_name);
		closedir(d);
	}
	std::sort(names.begin(), names.end()); // the fixed-width sequence orders them
	for (std::string &n : names)
		n = dir_ + "/" + n;
	return names;
}

Status Outbox::put(const std::string &uid, const std::string &bytes, const std::string &note,
		   std::string *ret_path)
{
	Status s = validate_uid(uid);
	if (!s.ok())
		return s;
	unsigned long long seq = 0;
	for (const std::string &p : pending()) {
		const std::string name = p.substr(dir_.size() + 1);
		seq = std::max(seq, std::stoull(name.substr(0, 10)));
		if (name.compare(11, uid.size(), uid) == 0 && name.size() == 11 + uid.size() + 4) {
			*ret_path = p; // already queued: once is enough
			return {};
		}
	}
	char head[16];
	std::snprintf(head, sizeof head, "%010llu_", seq + 1);
	const std::string path = dir_ + "/" + head + uid + ".dcm";
	if (!note.empty()) { // the note first: whoever sees the instance sees its note
		s = write_file_atomic(path + ".note", note.data(), note.size());
		if (!s.ok())
			return s;
	}
	s = write_file_atomic(path, bytes.data(), bytes.size());
	if (!s.ok())
		return s;
	*ret_path = path;
	return {};
}

Status Outbox::flush(const Pacs &pacs, std::vector<Sent> *ret_sent)
{
	ret_sent->clear();
	for (const std::string &path : pending()) {
		Status s = c_store(pacs, path);
		if (!s.ok())
			return s;
		const std::string name = path.substr(dir_.size() + 1);
		const std::string uid = name.substr(11, name.size() - 15);
		// Log first, then remove: a crash between the two resends one instance, which the PACS
		// (keyed by SOP instance UID) stores once; the other order could lose the record.
		const std::string line = uid + "\n";
		const int fd = ::open((dir_ + "/sent.log").c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0640);
		if (fd >= 0) {
			const ssize_t w = ::write(fd, line.data(), line.size());
			(void)w;
			fsync(fd);
			close(fd);
		}
		if (unlink(path.c_str()) < 0)
			return Status::error(-errno, path + ": sent but cannot remove: " + std::strerror(errno));
		Sent sent{uid, ""};
		std::ifstream note(path + ".note");
		if (note) {
			std::getline(note, sent.note, '\0');
			unlink((path + ".note").c_str());
		}
		ret_sent->push_back(sent);
	}
	return {};
}

} // namespace facescan::dicom
