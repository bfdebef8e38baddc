/* Storage driver: one contract run against the real (POSIX, in a temp dir) and the fake
 * backend, then what only the real filesystem shows: atomic replacement, leftovers of a
 * killed writer, a crash between delivery and spool cleanup, and kill -9 mid-write. */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/storage.h"
#include "facescan/storage_fake.h"
#include "drivers/storage_helpers.h"

struct env {
	char root[64], share[96], spool[96], away[96];
	const struct fscan_storage_ops *ops;
	struct fscan_storage *st;
	char *buf; /* last read_share result */
};

static struct env *env_new(const struct fscan_storage_ops *ops)
{
	struct env *e = calloc(1, sizeof(*e));
	snprintf(e->root, sizeof(e->root), "/tmp/fscan-storage-XXXXXX");
	assert_non_null(mkdtemp(e->root));
	snprintf(e->share, sizeof(e->share), "%s/share", e->root);
	snprintf(e->spool, sizeof(e->spool), "%s/spool", e->root);
	snprintf(e->away, sizeof(e->away), "%s/share-unmounted", e->root);
	assert_int_equal(mkdir(e->share, 0755), 0);
	e->ops = ops;
	struct fscan_storage_config cfg = {.share_dir = e->share, .spool_dir = e->spool, .min_free_bytes = 1};
	assert_int_equal(fscan_storage_create(ops, &cfg, &e->st), 0);
	return e;
}

static void env_free(struct env *e)
{
	fscan_storage_destroy(e->st);
	rm_rf(e->root);
	free(e->buf);
	free(e);
}

static void set_online(struct env *e, bool online)
{
	if (e->ops == &fscan_storage_fake_ops) {
		assert_int_equal(fscan_storage_fake_set_share_online(e->st, online), 0);
		return;
	}
	/* The real share "unmounts": its directory disappears. */
	assert_int_equal(online ? rename(e->away, e->share) : rename(e->share, e->away), 0);
}

/* Content of a delivered file as a NUL-terminated string, or NULL. */
static const char *read_share(struct env *e, const char *relpath)
{
	free(e->buf);
	e->buf = NULL;
	if (e->ops == &fscan_storage_fake_ops) {
		const void *d;
		size_t n;
		if (fscan_storage_fake_get(e->st, relpath, &d, &n) < 0)
			return NULL;
		e->buf = calloc(1, n + 1);
		memcpy(e->buf, d, n);
		return e->buf;
	}
	char path[512];
	snprintf(path, sizeof(path), "%s/%s", e->share, relpath);
	FILE *f = fopen(path, "rb");
	if (!f)
		return NULL;
	e->buf = calloc(1, 1 << 16);
	size_t n = fread(e->buf, 1, (1 << 16) - 1, f);
	e->buf[n] = '\0';
	fclose(f);
	return e->buf;
}

static int share_count(struct env *e)
{
	if (e->ops == &fscan_storage_fake_ops)
		return fscan_storage_fake_share_count(e->st);
	return count_files(e->share, NULL);
}

/* ---- the contract, run on both backends ---- */

static void contract_deliver(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops);
	assert_int_equal(fscan_storage_put(e->st, "P001/20261124T1200Z_s1.drc", "mesh", 4), FSCAN_STORAGE_DELIVERED);
	assert_string_equal(read_share(e, "P001/20261124T1200Z_s1.drc"), "mesh");
	assert_int_equal(fscan_storage_put(e->st, "P001/20261124T1200Z_s1.json", "{}", 2), FSCAN_STORAGE_DELIVERED);
	assert_int_equal(fscan_storage_put(e->st, "empty.txt", "", 0), FSCAN_STORAGE_DELIVERED);
	assert_string_equal(read_share(e, "empty.txt"), "");
	assert_int_equal(share_count(e), 3);
	assert_int_equal(fscan_storage_pending(e->st), 0);
	uint64_t free_bytes = 0;
	assert_int_equal(fscan_storage_share_free(e->st, &free_bytes), 0);
	assert_true(free_bytes > 0);
	env_free(e);
}

static void contract_spool_in_order_no_duplicates(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops);
	assert_int_equal(fscan_storage_put(e->st, "a/1", "one", 3), FSCAN_STORAGE_DELIVERED);
	set_online(e, false);
	assert_int_equal(fscan_storage_put(e->st, "a/2", "two", 3), FSCAN_STORAGE_SPOOLED);
	assert_int_equal(fscan_storage_put(e->st, "b/3", "three", 5), FSCAN_STORAGE_SPOOLED);
	assert_int_equal(fscan_storage_pending(e->st), 2);
	unsigned n = 99;
	assert_true(fscan_storage_flush(e->st, &n) < 0);
	assert_int_equal(n, 0);
	uint64_t free_bytes;
	assert_int_equal(fscan_storage_share_free(e->st, &free_bytes), -ENOENT);
	set_online(e, true);
	/* A new put flushes the older files first. */
	assert_int_equal(fscan_storage_put(e->st, "b/4", "four", 4), FSCAN_STORAGE_DELIVERED);
	assert_int_equal(fscan_storage_pending(e->st), 0);
	assert_string_equal(read_share(e, "a/2"), "two");
	assert_string_equal(read_share(e, "b/3"), "three");
	assert_string_equal(read_share(e, "b/4"), "four");
	assert_int_equal(share_count(e), 4);
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 0);
	if (ops == &fscan_storage_fake_ops) {
		const char *order[] = {"a/1", "a/2", "b/3", "b/4"};
		for (unsigned i = 0; i < 4; i++)
			assert_string_equal(fscan_storage_fake_delivery(e->st, i), order[i]);
		assert_null(fscan_storage_fake_delivery(e->st, 4));
	}
	env_free(e);
}

static void contract_flush_delivers(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops);
	set_online(e, false);
	for (int i = 0; i < 5; i++) {
		char name[32], body[32];
		snprintf(name, sizeof(name), "p/%d.json", i);
		snprintf(body, sizeof(body), "{\"i\":%d}", i);
		assert_int_equal(fscan_storage_put(e->st, name, body, strlen(body)), FSCAN_STORAGE_SPOOLED);
	}
	set_online(e, true);
	unsigned n = 0;
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 5);
	assert_int_equal(fscan_storage_pending(e->st), 0);
	assert_string_equal(read_share(e, "p/3.json"), "{\"i\":3}");
	assert_int_equal(share_count(e), 5);
	env_free(e);
}

static void contract_bad_relpaths(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops);
	const char *bad[] = {"", "/abs", "../up", "a/../b", "a//b", "a/", ".", "a/./b", "tab\there", "nl\n"};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++)
		assert_int_equal(fscan_storage_put(e->st, bad[i], "x", 1), -EINVAL);
	char longname[300];
	memset(longname, 'n', sizeof(longname) - 1);
	longname[sizeof(longname) - 1] = '\0';
	assert_int_equal(fscan_storage_put(e->st, longname, "x", 1), -EINVAL);
	assert_int_equal(fscan_storage_put(e->st, NULL, "x", 1), -EINVAL);
	assert_int_equal(fscan_storage_put(e->st, "ok", NULL, 1), -EINVAL);
	assert_int_equal(share_count(e), 0);
	assert_int_equal(fscan_storage_check_relpath("P-01/2026_x.drc"), 0);
	env_free(e);
}

static void test_posix_deliver(void **s) { (void)s; contract_deliver(&fscan_storage_posix_ops); }
static void test_fake_deliver(void **s) { (void)s; contract_deliver(&fscan_storage_fake_ops); }
static void test_posix_spool(void **s) { (void)s; contract_spool_in_order_no_duplicates(&fscan_storage_posix_ops); }
static void test_fake_spool(void **s) { (void)s; contract_spool_in_order_no_duplicates(&fscan_storage_fake_ops); }
static void test_posix_flush(void **s) { (void)s; contract_flush_delivers(&fscan_storage_posix_ops); }
static void test_fake_flush(void **s) { (void)s; contract_flush_delivers(&fscan_storage_fake_ops); }
static void test_posix_relpaths(void **s) { (void)s; contract_bad_relpaths(&fscan_storage_posix_ops); }
static void test_fake_relpaths(void **s) { (void)s; contract_bad_relpaths(&fscan_storage_fake_ops); }

/* ---- fake-only: full share and write failures ---- */

static void test_fake_full_and_failing_share(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_fake_ops);
	assert_int_equal(fscan_storage_fake_set_share_free(e->st, 10), 0);
	assert_int_equal(fscan_storage_put(e->st, "big", "0123456789abc", 13), FSCAN_STORAGE_SPOOLED);
	assert_int_equal(fscan_storage_fake_set_share_free(e->st, 1000), 0);
	assert_int_equal(fscan_storage_fake_fail_writes(e->st, 1, -EIO), 0);
	unsigned n;
	assert_int_equal(fscan_storage_flush(e->st, &n), -EIO);
	assert_int_equal(fscan_storage_pending(e->st), 1);
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 1);
	assert_string_equal(read_share(e, "big"), "0123456789abc");
	env_free(e);
}

/* ---- real filesystem only ---- */

static void test_posix_replace_is_atomic_and_mode(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_posix_ops);
	assert_int_equal(fscan_storage_put(e->st, "x/f", "old", 3), 0);
	assert_int_equal(fscan_storage_put(e->st, "x/f", "new!", 4), 0);
	assert_string_equal(read_share(e, "x/f"), "new!");
	char p[256];
	snprintf(p, sizeof(p), "%s/x/f", e->share);
	struct stat st;
	assert_int_equal(stat(p, &st), 0);
	assert_int_equal(st.st_mode & 0777, 0640);
	bool hidden = false;
	assert_int_equal(count_files(e->share, &hidden), 1);
	assert_false(hidden);
	/* The standalone helper. */
	assert_int_equal(fscan_write_file_atomic(e->share, "direct", "d", 1, 0600), 0);
	assert_string_equal(read_share(e, "direct"), "d");
	assert_int_equal(fscan_write_file_atomic(e->share, "a/b", "d", 1, 0600), -EINVAL);
	assert_int_equal(fscan_write_file_atomic(e->away, "x", "d", 1, 0600), -ENOENT);
	env_free(e);
}

static void test_posix_spool_survives_restart(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_posix_ops);
	set_online(e, false);
	assert_int_equal(fscan_storage_put(e->st, "r/1", "first", 5), FSCAN_STORAGE_SPOOLED);
	assert_int_equal(fscan_storage_put(e->st, "r/2", "second", 6), FSCAN_STORAGE_SPOOLED);
	/* The daemon restarts: a new handle on the same spool continues the sequence. */
	fscan_storage_destroy(e->st);
	struct fscan_storage_config cfg = {.share_dir = e->share, .spool_dir = e->spool, .min_free_bytes = 1};
	assert_int_equal(fscan_storage_create(&fscan_storage_posix_ops, &cfg, &e->st), 0);
	assert_int_equal(fscan_storage_pending(e->st), 2);
	assert_int_equal(fscan_storage_put(e->st, "r/3", "third", 5), FSCAN_STORAGE_SPOOLED);
	set_online(e, true);
	unsigned n;
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 3);
	assert_string_equal(read_share(e, "r/1"), "first");
	assert_string_equal(read_share(e, "r/3"), "third");
	env_free(e);
}

static void test_posix_crash_between_rename_and_unlink(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_posix_ops);
	set_online(e, false);
	assert_int_equal(fscan_storage_put(e->st, "c/scan.drc", "MESH", 4), FSCAN_STORAGE_SPOOLED);
	set_online(e, true);
	/* The crash: the file reached the share, the spool entry was never removed. Reproduce the
	 * state by hand: deliver a copy of the entry's file as the crashed flush had. */
	char dir[256];
	snprintf(dir, sizeof(dir), "%s/c", e->share);
	assert_int_equal(mkdir(dir, 0750), 0);
	assert_int_equal(fscan_write_file_atomic(dir, "scan.drc", "MESH", 4, 0640), 0);
	assert_int_equal(fscan_storage_pending(e->st), 1);
	unsigned n;
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 1);
	assert_int_equal(count_files(e->share, NULL), 1); /* not two */
	assert_string_equal(read_share(e, "c/scan.drc"), "MESH");
	assert_int_equal(fscan_storage_pending(e->st), 0);
	env_free(e);
}

static void test_posix_damaged_spool_entry_set_aside(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_posix_ops);
	set_online(e, false);
	assert_int_equal(fscan_storage_put(e->st, "d/good", "ok", 2), FSCAN_STORAGE_SPOOLED);
	char p[256];
	snprintf(p, sizeof(p), "%s/00000000000000000000.spool", e->spool); /* sorts first */
	FILE *f = fopen(p, "w");
	fputs("garbage", f);
	fclose(f);
	set_online(e, true);
	unsigned n;
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 1);
	assert_string_equal(read_share(e, "d/good"), "ok");
	snprintf(p, sizeof(p), "%s/00000000000000000000.spool.bad", e->spool);
	assert_int_equal(access(p, F_OK), 0);
	env_free(e);
}

static void test_posix_stale_temp_swept(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_posix_ops);
	/* A dead writer's temp file (pid of a child that exited) in the share and the spool. */
	pid_t child = fork();
	if (child == 0)
		_exit(0);
	assert_int_equal(waitpid(child, NULL, 0), child);
	char p[256];
	snprintf(p, sizeof(p), "%s/.fscan-tmp.%d.1.scan.drc", e->share, (int)child);
	FILE *f = fopen(p, "w");
	fputs("half", f);
	fclose(f);
	/* A live writer's (ours) is left alone. */
	char live[256];
	snprintf(live, sizeof(live), "%s/.fscan-tmp.%d.99.other", e->share, (int)getpid());
	f = fopen(live, "w");
	fclose(f);
	assert_int_equal(fscan_storage_put(e->st, "next", "n", 1), 0);
	assert_int_equal(access(p, F_OK), -1);
	assert_int_equal(access(live, F_OK), 0);
	unlink(live);
	env_free(e);
}

/* An unmounted share leaves an empty mount point: with a marker configured, that is "missing"
 * and files are spooled instead of landing on the local disk. */
static void test_posix_share_marker(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_posix_ops);
	fscan_storage_destroy(e->st);
	struct fscan_storage_config cfg = {.share_dir = e->share, .spool_dir = e->spool, .min_free_bytes = 1,
					   .share_marker = ".facescan-share"};
	assert_int_equal(fscan_storage_create(&fscan_storage_posix_ops, &cfg, &e->st), 0);
	assert_int_equal(fscan_storage_put(e->st, "m/1", "one", 3), FSCAN_STORAGE_SPOOLED);
	uint64_t free_bytes;
	assert_int_equal(fscan_storage_share_free(e->st, &free_bytes), -ENOENT);
	assert_int_equal(count_files(e->share, NULL), 0);
	/* "Mounted": the marker is there. */
	char p[256];
	snprintf(p, sizeof(p), "%s/.facescan-share", e->share);
	FILE *f = fopen(p, "w");
	fclose(f);
	assert_int_equal(fscan_storage_put(e->st, "m/2", "two", 3), FSCAN_STORAGE_DELIVERED);
	assert_string_equal(read_share(e, "m/1"), "one");
	assert_string_equal(read_share(e, "m/2"), "two");
	fscan_storage_destroy(e->st);
	cfg.share_marker = "a/b";
	assert_int_equal(fscan_storage_create(&fscan_storage_posix_ops, &cfg, &e->st), -EINVAL);
	e->st = NULL;
	env_free(e);
}

/* kill -9 of a writer in the middle of puts: whatever it left, the share shows only complete
 * files, and a restarted writer delivers its spool with nothing lost. */
static void test_posix_kill9_mid_write(void **s)
{
	(void)s;
	struct env *e = env_new(&fscan_storage_posix_ops);
	enum { SIZE = 1 << 20 };
	pid_t child = fork();
	if (child == 0) {
		struct fscan_storage *st;
		struct fscan_storage_config cfg = {.share_dir = e->share, .spool_dir = e->spool, .min_free_bytes = 1};
		if (fscan_storage_create(&fscan_storage_posix_ops, &cfg, &st) < 0)
			_exit(1);
		char *data = malloc(SIZE);
		for (int i = 0; i < 1000; i++) {
			memset(data, 'A' + i % 26, SIZE);
			char name[32];
			snprintf(name, sizeof(name), "k/%04d.bin", i);
			fscan_storage_put(st, name, data, SIZE);
		}
		_exit(0);
	}
	struct timespec ts = {0, 150 * 1000000L};
	nanosleep(&ts, NULL);
	kill(child, SIGKILL);
	int status;
	assert_int_equal(waitpid(child, &status, 0), child);
	/* Every visible file is complete and uniform. */
	char dir[256];
	snprintf(dir, sizeof(dir), "%s/k", e->share);
	DIR *d = opendir(dir);
	int complete = 0;
	if (d) {
		struct dirent *de;
		while ((de = readdir(d))) {
			if (de->d_name[0] == '.')
				continue;
			char p[512];
			snprintf(p, sizeof(p), "%s/%s", dir, de->d_name);
			struct stat st;
			assert_int_equal(stat(p, &st), 0);
			assert_int_equal(st.st_size, SIZE);
			complete++;
		}
		closedir(d);
	}
	printf("kill -9 after 150 ms: %d complete files on the share\n", complete);
	/* A restarted writer sweeps the dead one's temp file on its next put there. */
	assert_int_equal(fscan_storage_put(e->st, "k/after", "x", 1), 0);
	bool hidden = false;
	count_files(e->share, &hidden);
	assert_false(hidden);
	env_free(e);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_posix_deliver),
		cmocka_unit_test(test_fake_deliver),
		cmocka_unit_test(test_posix_spool),
		cmocka_unit_test(test_fake_spool),
		cmocka_unit_test(test_posix_flush),
		cmocka_unit_test(test_fake_flush),
		cmocka_unit_test(test_posix_relpaths),
		cmocka_unit_test(test_fake_relpaths),
		cmocka_unit_test(test_fake_full_and_failing_share),
		cmocka_unit_test(test_posix_replace_is_atomic_and_mode),
		cmocka_unit_test(test_posix_spool_survives_restart),
		cmocka_unit_test(test_posix_crash_between_rename_and_unlink),
		cmocka_unit_test(test_posix_damaged_spool_entry_set_aside),
		cmocka_unit_test(test_posix_stale_temp_swept),
		cmocka_unit_test(test_posix_share_marker),
		cmocka_unit_test(test_posix_kill9_mid_write),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
