/* Storage driver, scan entries (the daemon's spool): one contract run against the real (POSIX,
 * in a temp dir) and the fake backend: delivery with metadata last, a share that is not mounted
 * (nothing written under it, delivered exactly once when it is back), a crash mid-spool reported
 * failed at recovery, redelivery that replaces, the free-space check, the writable() probe. */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
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

#define MARKER ".facescan-share"
#define BASE "20260101T000001Z_aaaaaaaaaaaa"

struct env {
	char root[64], share[96], spool[96], marker[128];
	const struct fscan_storage_ops *ops;
	struct fscan_storage *st;
	char files[8][128]; /* relpaths given to on_file, in order */
	int n_files;
};

static void touch(const char *path)
{
	FILE *f = fopen(path, "w");
	assert_non_null(f);
	fclose(f);
}

static struct env *env_new(const struct fscan_storage_ops *ops, uint64_t min_free)
{
	struct env *e = calloc(1, sizeof(*e));
	snprintf(e->root, sizeof(e->root), "/tmp/fscan-scan-XXXXXX");
	assert_non_null(mkdtemp(e->root));
	snprintf(e->share, sizeof(e->share), "%s/share", e->root);
	snprintf(e->spool, sizeof(e->spool), "%s/spool", e->root);
	snprintf(e->marker, sizeof(e->marker), "%s/" MARKER, e->share);
	assert_int_equal(mkdir(e->share, 0755), 0);
	touch(e->marker);
	e->ops = ops;
	struct fscan_storage_config cfg = {.share_dir = e->share, .spool_dir = e->spool, .min_free_bytes = min_free,
					   .spool_min_free = 1, .share_marker = MARKER};
	assert_int_equal(fscan_storage_create(ops, &cfg, &e->st), 0);
	return e;
}

static void env_free(struct env *e)
{
	fscan_storage_destroy(e->st);
	rm_rf(e->root);
	free(e);
}

static bool is_fake(struct env *e)
{
	return e->ops == &fscan_storage_fake_ops;
}

/* The share is unmounted: the real one leaves its mount point, an empty local directory. */
static void set_mounted(struct env *e, bool mounted)
{
	if (is_fake(e)) {
		assert_int_equal(fscan_storage_fake_set_share_online(e->st, mounted), 0);
		return;
	}
	if (mounted)
		touch(e->marker);
	else
		assert_int_equal(unlink(e->marker), 0);
}

/* Files on the share, the marker not counted. */
static int share_count(struct env *e)
{
	if (is_fake(e))
		return fscan_storage_fake_share_count(e->st);
	return count_files(e->share, NULL) - (access(e->marker, F_OK) == 0);
}

static bool share_has(struct env *e, const char *relpath, const char *want)
{
	if (is_fake(e)) {
		const void *d;
		size_t n;
		return fscan_storage_fake_get(e->st, relpath, &d, &n) == 0 && n == strlen(want) && !memcmp(d, want, n);
	}
	char path[512], buf[256] = {0};
	snprintf(path, sizeof(path), "%s/%s", e->share, relpath);
	FILE *f = fopen(path, "rb");
	if (!f)
		return false;
	size_t n = fread(buf, 1, sizeof(buf) - 1, f);
	fclose(f);
	return n == strlen(want) && !memcmp(buf, want, n);
}

static void on_file(const char *relpath, void *ud)
{
	struct env *e = ud;
	assert_true(e->n_files < 8);
	snprintf(e->files[e->n_files++], sizeof(e->files[0]), "%s", relpath);
}

static const struct fscan_storage_file scan_files[] = {
	{BASE ".drc", "mesh", 4},
	{BASE ".json", "{}", 2},
	{BASE ".png", "png", 3},
};

static int queue(struct env *e, const char *base)
{
	return fscan_storage_queue(e->st, base, strrchr(base, '_') + 1, "P1", scan_files, 3);
}

static int deliver(struct env *e, struct fscan_storage_delivery *d)
{
	e->n_files = 0;
	return fscan_storage_deliver_next(e->st, d, on_file, e);
}

/* The driver's renames pass through here (test_storage_scan.ldflags: --wrap catches them, the
 * atomic write being its own object file). A child set to die at its n-th rename gets a real
 * SIGKILL there: the driver has no pause for a test to kill it in. */
int __real_renameat(int olddirfd, const char *oldpath, int newdirfd, const char *newpath);
static int kill_at_rename; /* 0: never */

int __wrap_renameat(int olddirfd, const char *oldpath, int newdirfd, const char *newpath)
{
	if (kill_at_rename && --kill_at_rename == 0)
		raise(SIGKILL);
	return __real_renameat(olddirfd, oldpath, newdirfd, newpath);
}

/* A process killed while it spools: the real backend gets a real kill -9 between two files
 * (in the rename of the second: the first file in place, the second a temp file, no manifest). */
static void crash_mid_queue(struct env *e, const char *base)
{
	if (is_fake(e)) {
		assert_int_equal(fscan_storage_fake_crash_next_queue(e->st, 1), 0);
		assert_int_equal(queue(e, base), -EINTR);
		return;
	}
	pid_t pid = fork();
	assert_true(pid >= 0);
	if (pid == 0) {
		kill_at_rename = 2;
		queue(e, base);
		_exit(0);
	}
	int status;
	assert_int_equal(waitpid(pid, &status, 0), pid);
	assert_true(WIFSIGNALED(status));
}

/* ---- the contract, run on both backends ---- */

static void contract_deliver_metadata_last(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops, 1);
	assert_int_equal(queue(e, BASE), 0);
	assert_int_equal(fscan_storage_scans(e->st), 1);
	assert_int_equal(fscan_storage_queued(e->st, "aaaaaaaaaaaa"), 1);
	assert_int_equal(fscan_storage_queued(e->st, "bbbbbbbbbbbb"), 0);
	struct fscan_storage_delivery d;
	assert_int_equal(deliver(e, &d), 1);
	assert_string_equal(d.base, BASE);
	assert_string_equal(d.scan_id, "aaaaaaaaaaaa");
	assert_string_equal(d.dir, "P1");
	assert_int_equal(e->n_files, 3);
	assert_string_equal(e->files[0], "P1/" BASE ".drc");
	assert_string_equal(e->files[1], "P1/" BASE ".png");
	assert_string_equal(e->files[2], "P1/" BASE ".json"); /* metadata last */
	assert_true(share_has(e, "P1/" BASE ".drc", "mesh"));
	assert_true(share_has(e, "P1/" BASE ".json", "{}"));
	assert_int_equal(deliver(e, &d), 0);
	assert_int_equal(fscan_storage_scans(e->st), 0);
	assert_int_equal(fscan_storage_queued(e->st, "aaaaaaaaaaaa"), 0);
	assert_int_equal(fscan_storage_queue(e->st, "a/b", "x", "P1", scan_files, 3), -EINVAL);
	assert_int_equal(fscan_storage_queue(e->st, BASE, "x", "..", scan_files, 3), -EINVAL);
	env_free(e);
}

/* Regression (issue 12): the share's directory is there but it is not mounted. */
static void contract_unmounted_share(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops, 1);
	set_mounted(e, false);
	assert_int_equal(queue(e, BASE), 0);
	struct fscan_storage_delivery d;
	assert_int_equal(deliver(e, &d), -ENOENT);
	assert_int_equal(e->n_files, 0);
	assert_int_equal(share_count(e), 0); /* nothing on the local disk under the mount point */
	if (!is_fake(e))
		assert_int_equal(count_files(e->share, NULL), 0);
	assert_int_equal(fscan_storage_scans(e->st), 1);
	assert_int_equal(fscan_storage_queued(e->st, "aaaaaaaaaaaa"), 1);
	set_mounted(e, true);
	assert_int_equal(deliver(e, &d), 1);
	assert_int_equal(deliver(e, &d), 0);
	assert_int_equal(share_count(e), 3); /* exactly once */
	if (is_fake(e))
		assert_null(fscan_storage_fake_delivery(e->st, 3));
	env_free(e);
}

static void collect(const char *id, void *ud)
{
	char *out = ud;
	strcat(out, id);
	strcat(out, ";");
}

/* Regression: a crash mid-spool is reported failed at the next start, never delivered. */
static void contract_crash_mid_spool(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops, 1);
	crash_mid_queue(e, "20260101T000002Z_cccccccccccc");
	assert_int_equal(fscan_storage_scans(e->st), 0);
	assert_int_equal(fscan_storage_queued(e->st, "cccccccccccc"), 0);
	struct fscan_storage_delivery d;
	assert_int_equal(deliver(e, &d), 0);
	char ids[128] = "";
	assert_int_equal(fscan_storage_recover(e->st, collect, ids), 1);
	assert_string_equal(ids, "cccccccccccc;");
	assert_int_equal(share_count(e), 0);
	env_free(e);
}

static void contract_recover_reports_ids(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops, 1);
	assert_int_equal(queue(e, BASE), 0); /* complete: survives recovery */
	crash_mid_queue(e, "20260101T000002Z_cccccccccccc");
	char ids[128] = "";
	if (!is_fake(e)) { /* an entry of the daemon's old spool is kept, not reported failed */
		char p[256];
		snprintf(p, sizeof(p), "%s/20251231T000000Z_dddddddddddd", e->spool);
		assert_int_equal(mkdir(p, 0750), 0);
		strcat(p, "/manifest.json");
		touch(p);
	}
	assert_int_equal(fscan_storage_recover(e->st, collect, ids), 1);
	assert_string_equal(ids, "cccccccccccc;");
	assert_int_equal(fscan_storage_recover(e->st, collect, ids), 0);
	assert_int_equal(fscan_storage_scans(e->st), 1);
	struct fscan_storage_delivery d;
	assert_int_equal(deliver(e, &d), 1);
	assert_string_equal(d.scan_id, "aaaaaaaaaaaa");
	assert_int_equal(share_count(e), 3);
	env_free(e);
}

/* Names are fixed per scan: the same entry delivered twice replaces, never duplicates. */
static void contract_redelivery_replaces(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops, 1);
	struct fscan_storage_delivery d;
	assert_int_equal(queue(e, BASE), 0);
	assert_int_equal(deliver(e, &d), 1);
	assert_int_equal(queue(e, BASE), 0);
	assert_int_equal(queue(e, BASE), 0); /* queued again: one entry */
	assert_int_equal(fscan_storage_scans(e->st), 1);
	assert_int_equal(deliver(e, &d), 1);
	assert_int_equal(share_count(e), 3);
	env_free(e);
}

static void contract_share_full(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops, 1ull << 60);
	assert_int_equal(queue(e, BASE), 0);
	struct fscan_storage_delivery d;
	assert_int_equal(deliver(e, &d), -ENOSPC);
	assert_int_equal(fscan_storage_scans(e->st), 1);
	assert_int_equal(share_count(e), 0);
	env_free(e);
}

static void contract_writable(const struct fscan_storage_ops *ops)
{
	struct env *e = env_new(ops, 1);
	assert_int_equal(fscan_storage_writable(e->st), 0);
	if (is_fake(e)) {
		assert_int_equal(fscan_storage_fake_set_spool_writable(e->st, false), 0);
		assert_int_equal(fscan_storage_writable(e->st), -EROFS);
		assert_int_equal(queue(e, BASE), -EROFS);
	} else {
		/* As root no mode bit stops a write: a file where the spool was does. */
		rm_rf(e->spool);
		touch(e->spool);
		assert_int_equal(fscan_storage_writable(e->st), -ENOTDIR);
		assert_true(queue(e, BASE) < 0);
		assert_int_equal(unlink(e->spool), 0);
		assert_int_equal(mkdir(e->spool, 0750), 0);
		assert_int_equal(fscan_storage_writable(e->st), 0); /* seen as it is now */
	}
	env_free(e);
}

#define BOTH(name)                                                                                 \
	static void test_posix_##name(void **s) { (void)s; contract_##name(&fscan_storage_posix_ops); } \
	static void test_fake_##name(void **s) { (void)s; contract_##name(&fscan_storage_fake_ops); }
BOTH(deliver_metadata_last)
BOTH(unmounted_share)
BOTH(crash_mid_spool)
BOTH(recover_reports_ids)
BOTH(redelivery_replaces)
BOTH(share_full)
BOTH(writable)

#define PAIR(name) cmocka_unit_test(test_posix_##name), cmocka_unit_test(test_fake_##name)

int main(void)
{
	const struct CMUnitTest tests[] = {
		PAIR(deliver_metadata_last), PAIR(unmounted_share),	PAIR(crash_mid_spool), PAIR(recover_reports_ids),
		PAIR(redelivery_replaces),   PAIR(share_full), PAIR(writable),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
