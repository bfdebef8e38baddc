// Patient IDs become folder names on the share: every refused class has its case.
#include "daemon/patient_id.hpp"


#include <string>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;

static void refused(const std::string &id, const char *reason)
{
	facescan::Status s = validate_patient_id(id);
	assert_false(s.ok());
	assert_int_equal(s.code(), -EINVAL);
	if (s.message().find(reason) == std::string::npos)
		fail_msg("want '%s', got '%s'", reason, s.message().c_str());
	// The reason never echoes the id (patient data stays out of logs).
	if (id.size() > 3)
		assert_true(s.message().find(id) == std::string::npos);
}

static void test_accepted(void **)
{
	assert_true(validate_patient_id("P-0001").ok());
	assert_true(validate_patient_id("mueller_anna.1984").ok());
	assert_true(validate_patient_id("a").ok());
	assert_true(validate_patient_id(std::string(kPatientIdMax, 'x')).ok());
	assert_true(validate_patient_id("a.b").ok());
}

static void test_empty(void **)
{
	refused("", "empty");
}

static void test_too_long(void **)
{
	refused(std::string(kPatientIdMax + 1, 'x'), "longer than 64");
	refused(std::string(10000, 'y'), "longer than 64");
}

static void test_separators(void **)
{
	refused("a/b", "path separator");
	refused("/etc", "path separator");
	refused("a\\b", "path separator");
	refused("../../etc/passwd", "path separator");
}

static void test_dotdot(void **)
{
	refused("..", "'..'");
	refused("a..b", "'..'");
	refused("x..", "'..'");
}

static void test_control_characters(void **)
{
	refused(std::string("a\nb"), "control character");
	refused(std::string("a\tb"), "control character");
	refused(std::string("a\x7f" "b"), "control character");
	refused(std::string("ab\x1b[31m"), "control character");
	refused(std::string("a\0b", 3), "control character");
}

static void test_leading_dot(void **)
{
	refused(".hidden", "starts with '.'");
	refused(".", "starts with '.'");
}

static void test_other_characters(void **)
{
	refused("a b", "may only contain");
	refused("a:b", "may only contain");
	refused("M\xc3\xbcller", "may only contain");
	refused("a*b", "may only contain");
}

// Folder names Windows / SMB shares cannot hold were accepted (CON, NUL, aux.txt, a.).
static void test_windows_reserved(void **)
{
	for (const char *id : {"CON", "con", "NUL", "aux.txt", "Prn", "COM1", "lpt9.x", "nul.tar.gz"})
		refused(id, "reserved device name");
	refused("a.", "ends with '.'");
	refused("abc.", "ends with '.'");
	for (const char *id : {"CONX", "COM10", "console", "NULL-1", "aux_1", "PAT.1"})
		assert_true(validate_patient_id(id).ok());
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_accepted),      cmocka_unit_test(test_empty),
		cmocka_unit_test(test_too_long),      cmocka_unit_test(test_separators),
		cmocka_unit_test(test_dotdot),        cmocka_unit_test(test_control_characters),
		cmocka_unit_test(test_leading_dot),   cmocka_unit_test(test_other_characters),
		cmocka_unit_test(test_windows_reserved),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
