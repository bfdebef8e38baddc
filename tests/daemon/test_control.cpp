// The control protocol: line framing (split, joined, oversize) and request parsing.
#include "daemon/control.hpp"


#include <cstring>
#include <string>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;

static void test_lines_split_and_joined(void **)
{
	LineReader r;
	std::string line;
	r.feed("{\"cmd\":", 7);
	assert_int_equal(static_cast<int>(r.next(&line)), static_cast<int>(LineReader::Result::need_more));
	const char rest[] = "\"status\"}\n{\"cmd\":\"last\"}\r\n{\"cmd";
	r.feed(rest, sizeof rest - 1);
	assert_int_equal(static_cast<int>(r.next(&line)), static_cast<int>(LineReader::Result::line));
	assert_string_equal(line.c_str(), "{\"cmd\":\"status\"}");
	assert_int_equal(static_cast<int>(r.next(&line)), static_cast<int>(LineReader::Result::line));
	assert_string_equal(line.c_str(), "{\"cmd\":\"last\"}");
	assert_int_equal(static_cast<int>(r.next(&line)), static_cast<int>(LineReader::Result::need_more));
}

static void test_oversize(void **)
{
	LineReader r;
	std::string big(kMaxRequest, 'x'), line;
	r.feed(big.data(), big.size()); // no newline within the limit
	assert_int_equal(static_cast<int>(r.next(&line)), static_cast<int>(LineReader::Result::too_large));
	// Poisoned: a later good line does not resynchronise inside the same connection.
	r.feed("{}\n", 3);
	assert_int_equal(static_cast<int>(r.next(&line)), static_cast<int>(LineReader::Result::too_large));

	LineReader r2;
	std::string exact(kMaxRequest - 1, 'y');
	exact += '\n';
	r2.feed(exact.data(), exact.size());
	assert_int_equal(static_cast<int>(r2.next(&line)), static_cast<int>(LineReader::Result::line));
	assert_int_equal(line.size(), kMaxRequest - 1);

	LineReader r3;
	std::string over(kMaxRequest, 'z');
	over += "\n";
	r3.feed(over.data(), over.size());
	assert_int_equal(static_cast<int>(r3.next(&line)), static_cast<int>(LineReader::Result::too_large));
}

static void test_requests(void **)
{
	Request q;
	assert_true(parse_request("{\"cmd\":\"scan\",\"patient\":\"P1\",\"wait\":true}", &q).ok());
	assert_int_equal(static_cast<int>(q.cmd), static_cast<int>(Request::Cmd::scan));
	assert_string_equal(q.patient.c_str(), "P1");
	assert_true(q.wait);
	assert_true(parse_request("{\"cmd\":\"status\"}", &q).ok());
	assert_int_equal(static_cast<int>(q.cmd), static_cast<int>(Request::Cmd::status));
	assert_true(parse_request("{\"cmd\":\"last\"}", &q).ok());
	assert_true(parse_request("{\"cmd\":\"cancel\"}", &q).ok());
	assert_true(parse_request("{\"cmd\":\"button\"}", &q).ok());
}

static void test_bad_requests(void **)
{
	const struct {
		const char *line;
		const char *why;
	} bad[] = {
		{"", "not valid JSON"},
		{"{\"cmd\":", "not valid JSON"},
		{"\x01\x02garbage", "not valid JSON"},
		{"[1,2]", "not a JSON object"},
		{"\"scan\"", "not a JSON object"},
		{"{}", "no \"cmd\""},
		{"{\"cmd\":7}", "no \"cmd\""},
		{"{\"cmd\":\"reboot\"}", "unknown cmd"},
		{"{\"cmd\":\"scan\"}", "needs \"patient\""},
		{"{\"cmd\":\"scan\",\"patient\":5}", "must be a string"},
		{"{\"cmd\":\"scan\",\"patient\":\"a\",\"wait\":\"yes\"}", "true or false"},
		{"{\"cmd\":\"status\",\"patient\":\"a\"}", "unknown field"},
		{"{\"cmd\":\"scan\",\"patient\":\"a\",\"x\":1}", "unknown field"},
	};
	for (const auto &b : bad) {
		Request q;
		q.patient = "untouched";
		facescan::Status s = parse_request(b.line, &q);
		if (s.ok() || s.message().find(b.why) == std::string::npos)
			fail_msg("'%s': want '%s', got '%s'", b.line, b.why, s.message().c_str());
		assert_string_equal(q.patient.c_str(), "untouched");
	}
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_lines_split_and_joined),
		cmocka_unit_test(test_oversize),
		cmocka_unit_test(test_requests),
		cmocka_unit_test(test_bad_requests),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
