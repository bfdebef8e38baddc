// A scan as a DICOM instance in the patient's study, and its way to the PACS.
//
// The instance is Encapsulated STL (SOP class 1.2.840.10008.5.1.4.1.1.104.3, modality M3D): one
// self-contained object per scan that every PACS stores and 3D Slicer / planning tools open.
// Encapsulated OBJ (104.4) would carry the texture but needs three linked instances (OBJ, MTL
// and the texture as a separate image) that must all arrive; the textured mesh stays on the
// share (.glb/.obj). See docs/clinic.md.
//
// DCMTK builds, writes, reads and sends the datasets (dcmdata, dcmnet's DcmSCU).
#pragma once

#include "common/status.hpp"

#include <chrono>
#include <string>
#include <vector>

namespace facescan::dicom {

/// Who and what the scan is for, from the scan request. Empty study_uid / accession: the
/// instance gets a new study UID and no accession number.
struct Subject {
	std::string patient_id;	  // LO, checked by daemon::validate_patient_id before
	std::string patient_name; // PN, "Family^Given^Middle^Prefix^Suffix"
	std::string accession;	  // SH
	std::string study_uid;	  // UI
};

/// DICOM's rules for the request fields (PS3.5 6.2), refused with -EINVAL and a reason that never
/// repeats the value (it is patient data):
///   name      <= 64 bytes, valid UTF-8, no control characters or '\', at most 5 '^' components
///             and no '=' (one component group); empty is allowed (PN is type 2)
///   accession <= 16 characters, printable ASCII without '\'; empty allowed
///   study uid <= 64 characters, digits and '.', components without leading zeros, not empty
Status validate_patient_name(const std::string &name);
Status validate_accession(const std::string &accession);
Status validate_uid(const std::string &uid);

/// A new UID under DCMTK's site root (dcmGenerateUniqueIdentifier).
std::string new_uid();

struct Equipment {
	std::string manufacturer = "facescan";
	std::string model = "facescan booth";
	std::string software_version;
	std::string device_serial; // e.g. the booth's calibration id
};

/// The identity of one built instance.
struct Instance {
	std::string sop_class_uid, sop_instance_uid, study_uid, series_uid;
};

/// Builds an Encapsulated STL instance holding `stl` (binary STL, millimetres) and returns the
/// DICOM file's bytes (Part 10, explicit VR little endian). -EINVAL for an empty document or a
/// field that fails the rules above, -EIO when DCMTK refuses.
Status encode_stl_instance(const std::string &stl, const Subject &subject, const Equipment &equipment,
			   std::chrono::system_clock::time_point when, std::string *ret_bytes,
			   Instance *ret_instance);

/// What a DICOM file holds, for checks: the identity, the patient id and the encapsulated document.
struct Parsed {
	Instance instance;
	std::string patient_id, patient_name, accession, mime_type, document;
};
/// -EINVAL when the bytes are not a DICOM file or lack an encapsulated document.
Status parse_instance(const std::string &bytes, Parsed *ret_parsed);

/// The PACS of the config: C-STORE from calling_ae to called_ae at host:port.
struct Pacs {
	std::string calling_ae = "FACESCAN", called_ae, host;
	int port = 104;
	int timeout_s = 10; // connect, association and each DIMSE message
};
/// -EINVAL for AE titles over 16 characters or with '\' / control characters, an empty host or
/// a port outside 1..65535.
Status validate_pacs(const Pacs &pacs);

/// Sends one DICOM file by C-STORE. -ECONNREFUSED / -ETIMEDOUT when the PACS cannot be reached
/// or the association is rejected (worth retrying), -EPROTO when it refuses the instance (a
/// failure status; the message names it), -ENOENT / -EINVAL for an unreadable file.
Status c_store(const Pacs &pacs, const std::string &path);

/// The DICOM spool: instances wait here, in the order they were put, until the PACS takes them.
/// Files are <dir>/<10-digit sequence>_<SOP instance UID>.dcm; a sent one is removed and its UID
/// appended to <dir>/sent.log (so a resend after a crash can be recognised; the PACS, keyed by
/// SOP instance UID, stores it once anyway). Only one process may use a directory at a time.
class Outbox {
public:
	explicit Outbox(std::string dir) : dir_(std::move(dir)) {}
	/// Creates the directory (mode 0750) when missing. -errno otherwise.
	Status open();
	/// Queues an instance atomically; returns its path. `note` (optional) is kept beside it
	/// (<name>.note) and handed back when it is sent: facescand puts the path of the scan's
	/// metadata there, to record the delivery. -EINVAL for a bad UID.
	Status put(const std::string &sop_instance_uid, const std::string &bytes, const std::string &note,
		   std::string *ret_path);
	/// Paths waiting, oldest first.
	std::vector<std::string> pending() const;
	struct Sent {
		std::string sop_instance_uid, note;
	};
	/// Sends the pending instances in order, stopping at the first that fails: 0 when all went,
	/// else the failure of the first that did not (it and the rest wait). ret_sent: what went.
	Status flush(const Pacs &pacs, std::vector<Sent> *ret_sent);
	const std::string &dir() const { return dir_; }

private:
	std::string dir_;
};

} // namespace facescan::dicom
