// Spool and delivery: atomic writes, share missing then back (delivered once, in order),
// interrupted entries reported failed, nothing partial on the share.
#include "daemon/spool.hpp"
#include "facescan/storage.h"
#include "facescan/storage_fake.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <dirent.h>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;

static std::string tmp;

static int setup(void **)
{
	char t[] = "/tmp/facescan-spool-XXXXXX";
	if (!mkdtemp(t))
		return -1;
	tmp = t;
	return 0;
}

static int teardown(void **)
{
	std::string cmd = "rm -rf '" + tmp + "'";
	return std::system(cmd.c_str());
}

static std::vector<std::string> ls(const std::string &dir)
{
	std::vector<std::string> out;
	DIR *d = opendir(dir.c_str());
	if (!d)
		return out;
	while (struct dirent *e = readdir(d))
		if (std::strcmp(e->d_name, ".") && std::strcmp(e->d_name, ".."))
			out.push_back(e->d_name);
	closedir(d);
	std::sort(out.begin(), out.end());
	return out;
}

static std::string slurp(const std::string &path)
{
	std::ifstream f(path);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}

static std::vector<SpoolFile> files_of(const std::string &base)
{
	return {{base + ".drc", "mesh-" + base}, {base + ".png", "png-" + base}, {base + ".json", "{\"b\":\"" + base + "\"}"}};
}

static void test_atomic_write(void **)
{
	const std::string dir = tmp + "/atomic";
	mkdir(dir.c_str(), 0755);
	// A temp file left by a crashed writer is removed by the next write of that name.
	std::ofstream(dir + "/.fscan-tmp.99999999.1.a.drc") << "half";
	assert_true(write_file_atomic(dir, "a.drc", "new contents").ok());
	assert_string_equal(slurp(dir + "/a.drc").c_str(), "new contents");
	std::vector<std::string> names = ls(dir);
	assert_int_equal(names.size(), 1);
	struct stat st;
	assert_int_equal(stat((dir + "/a.drc").c_str(), &st), 0);
	assert_int_equal(st.st_mode & 0777, 0640);
	facescan::Status s = write_file_atomic(tmp + "/no-such-dir", "a", "x");
	assert_int_equal(s.code(), -ENOENT);
}

static void test_deliver_now(void **)
{
	const std::string spool = tmp + "/s1", share = tmp + "/share1";
	mkdir(share.c_str(), 0755);
	Spool sp(spool, share, 0);
	assert_true(sp.init().ok());
	assert_true(sp.put("20260101T000000Z_aaaaaaaaaaaa", "aaaaaaaaaaaa", "P1", files_of("20260101T000000Z_aaaaaaaaaaaa")).ok());
	assert_int_equal(sp.pending(), 1);
	std::vector<Delivered> d;
	assert_true(sp.deliver(&d).ok());
	assert_int_equal(d.size(), 1);
	assert_string_equal(d[0].scan_id.c_str(), "aaaaaaaaaaaa");
	assert_int_equal(d[0].paths.size(), 3);
	// metadata last
	assert_non_null(std::strstr(d[0].paths[2].c_str(), ".json"));
	std::vector<std::string> got = ls(share + "/P1");
	assert_int_equal(got.size(), 3);
	assert_string_equal(slurp(share + "/P1/20260101T000000Z_aaaaaaaaaaaa.drc").c_str(), "mesh-20260101T000000Z_aaaaaaaaaaaa");
	assert_int_equal(sp.pending(), 0);
	assert_int_equal(ls(spool + "/queue").size(), 0);
}

static void test_share_missing_then_back(void **)
{
	const std::string spool = tmp + "/s2", share = tmp + "/share2";
	Spool sp(spool, share, 0);
	assert_true(sp.init().ok());
	const char *bases[] = {"20260101T000001Z_bbbbbbbbbbbb", "20260101T000002Z_cccccccccccc"};
	for (const char *b : bases)
		assert_true(sp.put(b, std::string(b).substr(17), "P2", files_of(b)).ok());
	std::vector<Delivered> d;
	facescan::Status s = sp.deliver(&d);
	assert_int_equal(s.code(), -ENOENT);
	assert_int_equal(d.size(), 0);
	assert_int_equal(sp.pending(), 2);
	struct stat st;
	assert_int_equal(stat(share.c_str(), &st), -1); // the share root is never created

	mkdir(share.c_str(), 0755);
	assert_true(sp.deliver(&d).ok());
	assert_int_equal(d.size(), 2);
	assert_string_equal(d[0].scan_id.c_str(), "bbbbbbbbbbbb"); // oldest first
	assert_string_equal(d[1].scan_id.c_str(), "cccccccccccc");
	assert_int_equal(ls(share + "/P2").size(), 6);
	// Delivered once: a second pass finds nothing to do.
	assert_true(sp.deliver(&d).ok());
	assert_int_equal(d.size(), 0);
	assert_int_equal(ls(share + "/P2").size(), 6);
}

static void test_share_full(void **)
{
	const std::string spool = tmp + "/s3", share = tmp + "/share3";
	mkdir(share.c_str(), 0755);
	Spool sp(spool, share, 1L << 30); // needs a petabyte free
	assert_true(sp.init().ok());
	assert_true(sp.put("20260101T000003Z_dddddddddddd", "dddddddddddd", "P3", files_of("x")).ok());
	std::vector<Delivered> d;
	assert_int_equal(sp.deliver(&d).code(), -ENOSPC);
	assert_int_equal(sp.pending(), 1);
	assert_int_equal(ls(share).size(), 0);
}

static void test_interrupted_entry_reported_failed(void **)
{
	const std::string spool = tmp + "/s4", share = tmp + "/share4";
	mkdir(share.c_str(), 0755);
	Spool sp(spool, share, 0);
	assert_true(sp.init().ok());
	// What a crash while spooling leaves: files, no manifest.
	const std::string dir = spool + "/queue/20260101T000004Z_eeeeeeeeeeee";
	mkdir(dir.c_str(), 0750);
	std::ofstream(dir + "/20260101T000004Z_eeeeeeeeeeee.drc") << "partial";
	// And what a crash after a delivery leaves: a hidden .done- folder.
	mkdir((spool + "/queue/.done-20260101T000000Z_ffffffffffff").c_str(), 0750);
	assert_int_equal(sp.pending(), 0);
	std::vector<Delivered> d;
	assert_true(sp.deliver(&d).ok());
	assert_int_equal(d.size(), 0); // never delivered
	std::vector<std::string> failed;
	assert_true(sp.recover(&failed).ok());
	assert_int_equal(failed.size(), 1);
	assert_string_equal(failed[0].c_str(), "eeeeeeeeeeee");
	assert_int_equal(ls(spool + "/queue").size(), 0);
	assert_int_equal(ls(share).size(), 0);
}

static void test_redelivery_after_crash_replaces(void **)
{
	// A crash after the files reached the share but before the entry left the queue:
	// delivering again rewrites the same names, no duplicates.
	const std::string spool = tmp + "/s5", share = tmp + "/share5";
	mkdir(share.c_str(), 0755);
	Spool sp(spool, share, 0);
	assert_true(sp.init().ok());
	const std::string b = "20260101T000005Z_111111111111";
	assert_true(sp.put(b, "111111111111", "P5", files_of(b)).ok());
	mkdir((share + "/P5").c_str(), 0750);
	std::ofstream(share + "/P5/" + b + ".drc") << "mesh-" << b;
	std::ofstream(share + "/P5/.fscan-tmp.99999998.3." + b + ".png") << "half";
	std::vector<Delivered> d;
	assert_true(sp.deliver(&d).ok());
	std::vector<std::string> got = ls(share + "/P5");
	assert_int_equal(got.size(), 3);
	for (const std::string &n : got)
		assert_true(n[0] != '.');
}

// An unmounted share leaves its mount point: an empty local directory. With a marker, a scan
// waits in the spool instead of landing on the local disk, and is delivered once mounted.
static void test_share_not_mounted(void **)
{
	const std::string spool = tmp + "/s9", share = tmp + "/share9";
	mkdir(share.c_str(), 0755); // the bare mount point
	Spool sp(spool, share, 0, ".facescan-share");
	assert_true(sp.init().ok());
	const std::string base = "20260101T000009Z_999999999999";
	assert_true(sp.put(base, "999999999999", "P9", files_of(base)).ok());
	std::vector<Delivered> d;
	facescan::Status s = sp.deliver(&d);
	std::printf("  %s\n", s.message().c_str());
	assert_int_equal(s.code(), -ENOENT);
	assert_non_null(std::strstr(s.message().c_str(), "not mounted"));
	assert_int_equal(d.size(), 0);
	assert_int_equal(ls(share).size(), 0); // nothing on the local disk under the mount point
	assert_int_equal(sp.pending(), 1);
	std::ofstream(share + "/.facescan-share") << "";
	assert_true(sp.deliver(&d).ok());
	assert_int_equal(d.size(), 1);
	assert_int_equal(ls(share + "/P9").size(), 3);
	assert_true(sp.deliver(&d).ok()); // exactly once
	assert_int_equal(d.size(), 0);
	assert_int_equal(ls(share + "/P9").size(), 3);
	assert_int_equal(sp.pending(), 0);
	// the driver's guard itself
	assert_int_equal(fscan_storage_share_present(share.c_str(), ".facescan-share"), 0);
	assert_int_equal(fscan_storage_share_present(share.c_str(), "no-such-marker"), -ENOENT);
	assert_int_equal(fscan_storage_share_present(share.c_str(), nullptr), 0);
	assert_int_equal(fscan_storage_share_present((tmp + "/nowhere").c_str(), nullptr), -ENOENT);
	assert_int_equal(fscan_storage_share_present((share + "/.facescan-share").c_str(), nullptr), -ENOTDIR);
	assert_int_equal(fscan_storage_share_present(share.c_str(), "a/b"), -EINVAL);
}

// The same face over the driver's fake backend: a crash mid-spool is reported failed, a
// complete scan is delivered with its paths.
static void test_fake_backend(void **)
{
	Spool sp(tmp + "/s10", "/nonexistent-share", 0, "", &fscan_storage_fake_ops);
	assert_true(sp.init().ok());
	const std::string a = "20260101T000010Z_aaaaaaaaaaaa", b = "20260101T000011Z_bbbbbbbbbbbb";
	assert_int_equal(fscan_storage_fake_crash_next_queue(sp.handle(), 1), 0);
	assert_int_equal(sp.put(a, "aaaaaaaaaaaa", "P10", files_of(a)).code(), -EINTR);
	assert_true(sp.put(b, "bbbbbbbbbbbb", "P10", files_of(b)).ok());
	assert_false(sp.queued("aaaaaaaaaaaa"));
	assert_true(sp.queued("bbbbbbbbbbbb"));
	std::vector<std::string> failed;
	assert_true(sp.recover(&failed).ok());
	assert_int_equal(failed.size(), 1);
	assert_string_equal(failed[0].c_str(), "aaaaaaaaaaaa");
	assert_int_equal(fscan_storage_fake_set_share_online(sp.handle(), false), 0);
	std::vector<Delivered> d;
	assert_int_equal(sp.deliver(&d).code(), -ENOENT);
	assert_int_equal(sp.pending(), 1);
	assert_int_equal(fscan_storage_fake_set_share_online(sp.handle(), true), 0);
	assert_true(sp.deliver(&d).ok());
	assert_int_equal(d.size(), 1);
	assert_string_equal(d[0].patient_id.c_str(), "P10");
	assert_string_equal(d[0].paths[2].c_str(), ("/nonexistent-share/P10/" + b + ".json").c_str());
	assert_int_equal(fscan_storage_fake_share_count(sp.handle()), 3);
	assert_int_equal(sp.pending(), 0);
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_atomic_write),
		cmocka_unit_test(test_deliver_now),
		cmocka_unit_test(test_share_missing_then_back),
		cmocka_unit_test(test_share_full),
		cmocka_unit_test(test_interrupted_entry_reported_failed),
		cmocka_unit_test(test_redelivery_after_crash_replaces),
		cmocka_unit_test(test_share_not_mounted),
		cmocka_unit_test(test_fake_backend),
	};
	return cmocka_run_group_tests(tests, setup, teardown);
}
