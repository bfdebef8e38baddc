// The DICOM instance and spool without a network: the request fields' rules (each refusal), an
// Encapsulated STL instance round trip through DCMTK, and the spool's order and idempotence.
// Delivery to a real PACS is tests/dicom/test_orthanc.sh.
#include "dicom/dicom.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

extern "C" {
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
}

namespace dcm = facescan::dicom;

static void test_name_rules(void **)
{
	assert_true(dcm::validate_patient_name("").ok());
	assert_true(dcm::validate_patient_name("Doe^Jane").ok());
	assert_true(dcm::validate_patient_name("Müller^Anna^^Dr.").ok());
	assert_int_equal(dcm::validate_patient_name(std::string(65, 'a')).code(), -EINVAL);
	assert_int_equal(dcm::validate_patient_name("Doe\\Jane").code(), -EINVAL);
	assert_int_equal(dcm::validate_patient_name("Doe\nJane").code(), -EINVAL);
	assert_int_equal(dcm::validate_patient_name("Doe=Jane").code(), -EINVAL);
	assert_int_equal(dcm::validate_patient_name("a^b^c^d^e^f").code(), -EINVAL);
	assert_int_equal(dcm::validate_patient_name("bad \xc3").code(), -EINVAL); // cut UTF-8
	// The reason never repeats the value (it is patient data).
	assert_null(std::strstr(dcm::validate_patient_name("Secret\\Name").message().c_str(), "Secret"));
}

static void test_accession_rules(void **)
{
	assert_true(dcm::validate_accession("").ok());
	assert_true(dcm::validate_accession("ACC-2026/0001").ok());
	assert_int_equal(dcm::validate_accession(std::string(17, '1')).code(), -EINVAL);
	assert_int_equal(dcm::validate_accession("A\\B").code(), -EINVAL);
	assert_int_equal(dcm::validate_accession("A\tB").code(), -EINVAL);
	assert_int_equal(dcm::validate_accession("Zürich").code(), -EINVAL);
}

static void test_uid_rules(void **)
{
	assert_true(dcm::validate_uid("1.2.840.10008.5.1.4.1.1.104.3").ok());
	assert_true(dcm::validate_uid("2.25.0").ok());
	assert_true(dcm::validate_uid(dcm::new_uid()).ok());
	assert_int_equal(dcm::validate_uid("").code(), -EINVAL);
	assert_int_equal(dcm::validate_uid("1.2.03").code(), -EINVAL);
	assert_int_equal(dcm::validate_uid("1..2").code(), -EINVAL);
	assert_int_equal(dcm::validate_uid(".1.2").code(), -EINVAL);
	assert_int_equal(dcm::validate_uid("1.2.").code(), -EINVAL);
	assert_int_equal(dcm::validate_uid("1.2.a").code(), -EINVAL);
	assert_int_equal(dcm::validate_uid("1." + std::string(63, '1')).code(), -EINVAL);
}

static void test_pacs_rules(void **)
{
	dcm::Pacs p;
	p.called_ae = "PACS";
	p.host = "127.0.0.1";
	assert_true(dcm::validate_pacs(p).ok());
	p.called_ae = std::string(17, 'A');
	assert_int_equal(dcm::validate_pacs(p).code(), -EINVAL);
	p.called_ae = "PACS";
	p.port = 0;
	assert_int_equal(dcm::validate_pacs(p).code(), -EINVAL);
	p.port = 104;
	p.calling_ae = "A\\B";
	assert_int_equal(dcm::validate_pacs(p).code(), -EINVAL);
}

static void test_instance_round_trip(void **)
{
	std::string stl(84 + 50, '\0');
	stl[80] = 1;
	stl[100] = 'x';
	dcm::Subject who{"P-7", "Doe^Jane", "A1", "1.2.3.4"};
	dcm::Equipment eq;
	eq.software_version = "test";
	std::string bytes;
	dcm::Instance inst;
	assert_true(dcm::encode_stl_instance(stl, who, eq, std::chrono::system_clock::now(), &bytes, &inst).ok());
	assert_string_equal(inst.sop_class_uid.c_str(), "1.2.840.10008.5.1.4.1.1.104.3");
	assert_string_equal(inst.study_uid.c_str(), "1.2.3.4");
	dcm::Parsed p;
	assert_true(dcm::parse_instance(bytes, &p).ok());
	assert_true(p.document == stl);
	assert_string_equal(p.patient_id.c_str(), "P-7");
	assert_string_equal(p.patient_name.c_str(), "Doe^Jane");
	assert_string_equal(p.accession.c_str(), "A1");
	assert_string_equal(p.mime_type.c_str(), "model/stl");
	assert_string_equal(p.instance.sop_instance_uid.c_str(), inst.sop_instance_uid.c_str());
	// No study given: a new one, distinct per instance.
	dcm::Instance i2, i3;
	who.study_uid.clear();
	assert_true(dcm::encode_stl_instance(stl, who, eq, std::chrono::system_clock::now(), &bytes, &i2).ok());
	assert_true(dcm::encode_stl_instance(stl, who, eq, std::chrono::system_clock::now(), &bytes, &i3).ok());
	assert_true(i2.study_uid != i3.study_uid && i2.sop_instance_uid != i3.sop_instance_uid);
	// Refusals: bad fields, empty document, not DICOM.
	who.accession = "A\\B";
	assert_int_equal(dcm::encode_stl_instance(stl, who, eq, {}, &bytes, &i2).code(), -EINVAL);
	who.accession = "";
	who.study_uid = "1.02";
	assert_int_equal(dcm::encode_stl_instance(stl, who, eq, {}, &bytes, &i2).code(), -EINVAL);
	who.study_uid = "";
	assert_int_equal(dcm::encode_stl_instance("", who, eq, {}, &bytes, &i2).code(), -EINVAL);
	assert_int_equal(dcm::parse_instance(std::string(200, 'x'), &p).code(), -EINVAL);
}

static void test_outbox_order(void **)
{
	char tmpl[] = "/tmp/facescan-outbox.XXXXXX";
	assert_non_null(mkdtemp(tmpl));
	dcm::Outbox box(std::string(tmpl) + "/dicom");
	assert_true(box.open().ok());
	std::string a, b, again;
	assert_true(box.put("1.2.3", "first", "note-a", &a).ok());
	assert_true(box.put("1.2.4", "second", "", &b).ok());
	assert_true(box.put("1.2.3", "first", "", &again).ok()); // queued once
	assert_string_equal(a.c_str(), again.c_str());
	assert_int_equal(box.put("1.02", "bad", "", &again).code(), -EINVAL);
	const std::vector<std::string> p = box.pending();
	assert_int_equal(p.size(), 2);
	assert_string_equal(p[0].c_str(), a.c_str());
	assert_string_equal(p[1].c_str(), b.c_str());
	// A PACS that is not there: nothing sent, nothing lost.
	dcm::Pacs pacs;
	pacs.called_ae = "NONE";
	pacs.host = "127.0.0.1";
	pacs.port = 1; // nothing listens on port 1 here
	pacs.timeout_s = 1;
	std::vector<dcm::Outbox::Sent> sent;
	const facescan::Status s = box.flush(pacs, &sent);
	assert_int_equal(s.code(), -ECONNREFUSED);
	assert_int_equal(sent.size(), 0);
	assert_int_equal(box.pending().size(), 2);
	const std::string cmd = std::string("rm -rf '") + tmpl + "'";
	assert_int_equal(std::system(cmd.c_str()), 0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_name_rules),	    cmocka_unit_test(test_accession_rules),
		cmocka_unit_test(test_uid_rules),	    cmocka_unit_test(test_pacs_rules),
		cmocka_unit_test(test_instance_round_trip), cmocka_unit_test(test_outbox_order),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
