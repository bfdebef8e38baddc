// Encapsulated STL instances (PS3.3 A.85.1): built, written and read with DCMTK's dcmdata.
#include "dicom/dicom.hpp"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcistrmb.h>
#include <dcmtk/dcmdata/dcostrmb.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmdata/dcwcache.h>
#include <dcmtk/oflog/oflog.h>

#include <ctime>
#include <mutex>

namespace facescan::dicom {

namespace {

// DCMTK logs to stderr by default; a library here does not log.
void quiet_dcmtk()
{
	static std::once_flag once;
	std::call_once(once, [] { OFLog::configure(OFLogger::OFF_LOG_LEVEL); });
}

bool valid_utf8(const std::string &s)
{
	for (size_t i = 0; i < s.size();) {
		const unsigned char c = static_cast<unsigned char>(s[i]);
		const size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
		if (n == 0 || i + n > s.size())
			return false;
		for (size_t k = 1; k < n; ++k)
			if ((static_cast<unsigned char>(s[i + k]) >> 6) != 0x2)
				return false;
		i += n;
	}
	return true;
}

std::string dicom_date(const std::tm &tm)
{
	char b[16];
	std::strftime(b, sizeof b, "%Y%m%d", &tm);
	return b;
}

std::string dicom_time(const std::tm &tm)
{
	char b[16];
	std::strftime(b, sizeof b, "%H%M%S", &tm);
	return b;
}

Status check(const OFCondition &c, const char *what)
{
	if (c.good())
		return {};
	return Status::error(-EIO, std::string("DICOM ") + what + ": " + c.text());
}

std::string get(DcmDataset *ds, const DcmTagKey &tag)
{
	OFString v;
	return ds->findAndGetOFStringArray(tag, v).good() ? std::string(v.c_str()) : std::string();
}

} // namespace

Status validate_patient_name(const std::string &name)
{
	if (name.size() > 64)
		return Status::error(-EINVAL, "patient name longer than 64 bytes");
	if (!valid_utf8(name))
		return Status::error(-EINVAL, "patient name is not valid UTF-8");
	int carets = 0;
	for (char ch : name) {
		const unsigned char u = static_cast<unsigned char>(ch);
		if (u < 0x20 || u == 0x7f)
			return Status::error(-EINVAL, "patient name contains a control character");
		if (ch == '\\')
			return Status::error(-EINVAL, "patient name contains '\\' (DICOM's value separator)");
		if (ch == '=')
			return Status::error(-EINVAL, "patient name contains '=' (only one component group)");
		carets += ch == '^';
	}
	if (carets > 4)
		return Status::error(-EINVAL, "patient name has more than 5 '^'-separated components");
	return {};
}

Status validate_accession(const std::string &accession)
{
	if (accession.size() > 16)
		return Status::error(-EINVAL, "accession number longer than 16 characters");
	for (char ch : accession) {
		const unsigned char u = static_cast<unsigned char>(ch);
		if (u < 0x20 || u >= 0x7f)
			return Status::error(-EINVAL, "accession number may only contain printable ASCII");
		if (ch == '\\')
			return Status::error(-EINVAL, "accession number contains '\\'");
	}
	return {};
}

Status validate_uid(const std::string &uid)
{
	if (uid.empty())
		return Status::error(-EINVAL, "UID is empty");
	if (uid.size() > 64)
		return Status::error(-EINVAL, "UID longer than 64 characters");
	size_t start = 0;
	while (true) {
		const size_t dot = uid.find('.', start);
		const std::string comp = uid.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
		if (comp.empty())
			return Status::error(-EINVAL, "UID has an empty component");
		for (char ch : comp)
			if (ch < '0' || ch > '9')
				return Status::error(-EINVAL, "UID may only contain digits and '.'");
		if (comp.size() > 1 && comp[0] == '0')
			return Status::error(-EINVAL, "UID component with a leading zero");
		if (dot == std::string::npos)
			break;
		start = dot + 1;
	}
	return {};
}

std::string new_uid()
{
	char buf[100];
	dcmGenerateUniqueIdentifier(buf, SITE_INSTANCE_UID_ROOT);
	return buf;
}

Status encode_stl_instance(const std::string &stl, const Subject &subject, const Equipment &equipment,
			   std::chrono::system_clock::time_point when, std::string *ret_bytes, Instance *ret_instance)
{
	quiet_dcmtk();
	if (stl.empty())
		return Status::error(-EINVAL, "empty STL document");
	if (subject.patient_id.empty() || subject.patient_id.size() > 64)
		return Status::error(-EINVAL, "patient id must be 1..64 characters");
	Status s = validate_patient_name(subject.patient_name);
	if (s.ok())
		s = validate_accession(subject.accession);
	if (s.ok() && !subject.study_uid.empty())
		s = validate_uid(subject.study_uid);
	if (!s.ok())
		return s;

	Instance inst;
	inst.sop_class_uid = UID_EncapsulatedSTLStorage;
	inst.sop_instance_uid = new_uid();
	inst.series_uid = new_uid();
	inst.study_uid = subject.study_uid.empty() ? new_uid() : subject.study_uid;
	const std::time_t tt = std::chrono::system_clock::to_time_t(when);
	std::tm tm{};
	gmtime_r(&tt, &tm);
	const std::string date = dicom_date(tm), time = dicom_time(tm);

	DcmFileFormat file;
	DcmDataset *ds = file.getDataset();
	const std::pair<DcmTagKey, std::string> fields[] = {
		{DCM_SpecificCharacterSet, "ISO_IR 192"}, // UTF-8: names with accents as typed
		{DCM_SOPClassUID, inst.sop_class_uid},
		{DCM_SOPInstanceUID, inst.sop_instance_uid},
		// Patient (type 2 fields are present, empty when unknown)
		{DCM_PatientName, subject.patient_name},
		{DCM_PatientID, subject.patient_id},
		{DCM_PatientBirthDate, ""},
		{DCM_PatientSex, ""},
		// General Study
		{DCM_StudyInstanceUID, inst.study_uid},
		{DCM_StudyDate, date},
		{DCM_StudyTime, time},
		{DCM_ReferringPhysicianName, ""},
		{DCM_StudyID, ""},
		{DCM_AccessionNumber, subject.accession},
		// Encapsulated Document Series
		{DCM_Modality, "M3D"},
		{DCM_SeriesInstanceUID, inst.series_uid},
		{DCM_SeriesNumber, "1"},
		// Frame of Reference (Manufacturing 3D Model)
		{DCM_FrameOfReferenceUID, new_uid()},
		{DCM_PositionReferenceIndicator, ""},
		// Enhanced General Equipment
		{DCM_Manufacturer, equipment.manufacturer},
		{DCM_ManufacturerModelName, equipment.model},
		{DCM_SoftwareVersions, equipment.software_version},
		{DCM_DeviceSerialNumber, equipment.device_serial.empty() ? "unknown" : equipment.device_serial},
		// Encapsulated Document
		{DCM_InstanceNumber, "1"},
		{DCM_ContentDate, date},
		{DCM_ContentTime, time},
		{DCM_AcquisitionDateTime, date + time},
		{DCM_BurnedInAnnotation, "NO"},
		{DCM_DocumentTitle, "3D face surface scan"},
		{DCM_MIMETypeOfEncapsulatedDocument, "model/stl"},
	};
	for (const auto &[tag, value] : fields) {
		s = check(ds->putAndInsertString(tag, value.c_str()), "attribute");
		if (!s.ok())
			return s;
	}
	s = check(ds->insertEmptyElement(DCM_ConceptNameCodeSequence), "concept name");
	if (!s.ok())
		return s;
	// Manufacturing 3D Model: the mesh is in millimetres (UCUM "mm").
	DcmItem *units = nullptr;
	s = check(ds->findOrCreateSequenceItem(DCM_MeasurementUnitsCodeSequence, units, 0), "units");
	if (!s.ok())
		return s;
	units->putAndInsertString(DCM_CodeValue, "mm");
	units->putAndInsertString(DCM_CodingSchemeDesignator, "UCUM");
	units->putAndInsertString(DCM_CodeMeaning, "millimeter");
	s = check(ds->putAndInsertUint8Array(DCM_EncapsulatedDocument,
					      reinterpret_cast<const Uint8 *>(stl.data()), unsigned(stl.size())),
		  "document");
	if (s.ok())
		s = check(ds->putAndInsertUint32(DCM_EncapsulatedDocumentLength, Uint32(stl.size())), "length");
	if (!s.ok())
		return s;

	// Part 10 file into memory: meta header, then the dataset, explicit VR little endian.
	s = check(file.validateMetaInfo(EXS_LittleEndianExplicit), "meta header");
	if (!s.ok())
		return s;
	const size_t cap = stl.size() + 64 * 1024;
	std::string out(cap, '\0');
	DcmOutputBufferStream stream(&out[0], offile_off_t(cap));
	file.transferInit();
	const OFCondition c = file.write(stream, EXS_LittleEndianExplicit, EET_ExplicitLength, nullptr);
	file.transferEnd();
	s = check(c, "encoding");
	if (!s.ok())
		return s;
	void *buf = nullptr;
	offile_off_t len = 0;
	stream.flushBuffer(buf, len);
	out.resize(size_t(len));
	*ret_bytes = std::move(out);
	*ret_instance = inst;
	return {};
}

Status parse_instance(const std::string &bytes, Parsed *ret_parsed)
{
	quiet_dcmtk();
	if (bytes.size() < 132 || bytes.compare(128, 4, "DICM") != 0)
		return Status::error(-EINVAL, "not a DICOM Part 10 file");
	DcmInputBufferStream in;
	in.setBuffer(bytes.data(), offile_off_t(bytes.size()));
	in.setEos();
	DcmFileFormat file;
	file.transferInit();
	const OFCondition c = file.read(in);
	file.transferEnd();
	if (c.bad())
		return Status::error(-EINVAL, std::string("DICOM parse: ") + c.text());
	DcmDataset *ds = file.getDataset();
	Parsed p;
	p.instance.sop_class_uid = get(ds, DCM_SOPClassUID);
	p.instance.sop_instance_uid = get(ds, DCM_SOPInstanceUID);
	p.instance.study_uid = get(ds, DCM_StudyInstanceUID);
	p.instance.series_uid = get(ds, DCM_SeriesInstanceUID);
	p.patient_id = get(ds, DCM_PatientID);
	p.patient_name = get(ds, DCM_PatientName);
	p.accession = get(ds, DCM_AccessionNumber);
	p.mime_type = get(ds, DCM_MIMETypeOfEncapsulatedDocument);
	const Uint8 *doc = nullptr;
	unsigned long n = 0;
	if (ds->findAndGetUint8Array(DCM_EncapsulatedDocument, doc, &n).bad() || !doc)
		return Status::error(-EINVAL, "DICOM file has no encapsulated document");
	Uint32 len = 0;
	if (ds->findAndGetUint32(DCM_EncapsulatedDocumentLength, len).good() && len <= n)
		n = len; // the value is padded to even length
	p.document.assign(reinterpret_cast<const char *>(doc), n);
	*ret_parsed = std::move(p);
	return {};
}

} // namespace facescan::dicom
