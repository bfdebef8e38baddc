/* Storage driver (real backend) with system calls failing on cue: -Wl,--wrap on write, fsync,
 * renameat, statvfs and unlinkat (see the .ldflags). The driver's calls live in other object
 * files (drivers/storage/storage_atomic.c, storage_posix.c), which is what --wrap needs. Each wrapper passes through to the
 * real call unless a test armed a failure. */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/storage.h"

ssize_t __real_write(int fd, const void *buf, size_t n);
int __real_fsync(int fd);
int __real_renameat(int olddirfd, const char *oldpath, int newdirfd, const char *newpath);
int __real_statvfs(const char *path, struct statvfs *buf);
int __real_unlinkat(int dirfd, const char *path, int flags);

/* A failure armed for the n-th next call (1 = the next one) of one wrapped function. */
struct cue {
	int countdown; /* 0 = disarmed */
	int err;
	int calls;
	bool sticky; /* keep failing after the first failure */
};
static struct cue cue_write, cue_fsync, cue_rename, cue_unlink;
static size_t write_chunk;          /* >0: write at most this many bytes per call */
static const char *statvfs_low_dir; /* statvfs of a path starting with this reports 100 bytes */

static bool fire(struct cue *c)
{
	c->calls++;
	if (c->countdown && --c->countdown == 0) {
		if (c->sticky)
			c->countdown = 1;
		errno = c->err;
		return true;
	}
	return false;
}

static void arm(struct cue *c, int nth, int err)
{
	c->countdown = nth;
	c->err = err;
}

ssize_t __wrap_write(int fd, const void *buf, size_t n)
{
	if (fire(&cue_write))
		return -1;
	if (write_chunk && n > write_chunk)
		n = write_chunk;
	return __real_write(fd, buf, n);
}

int __wrap_fsync(int fd)
{
	return fire(&cue_fsync) ? -1 : __real_fsync(fd);
}

int __wrap_renameat(int olddirfd, const char *oldpath, int newdirfd, const char *newpath)
{
	return fire(&cue_rename) ? -1 : __real_renameat(olddirfd, oldpath, newdirfd, newpath);
}

int __wrap_statvfs(const char *path, struct statvfs *buf)
{
	int r = __real_statvfs(path, buf);
	if (r == 0 && statvfs_low_dir && !strncmp(path, statvfs_low_dir, strlen(statvfs_low_dir))) {
		buf->f_bavail = 100;
		buf->f_frsize = 1;
	}
	return r;
}

int __wrap_unlinkat(int dirfd, const char *path, int flags)
{
	return fire(&cue_unlink) ? -1 : __real_unlinkat(dirfd, path, flags);
}

struct env {
	char root[64], share[96], spool[96];
	struct fscan_storage *st;
};

static int setup(void **state)
{
	struct env *e = calloc(1, sizeof(*e));
	snprintf(e->root, sizeof(e->root), "/tmp/fscan-faults-XXXXXX");
	assert_non_null(mkdtemp(e->root));
	snprintf(e->share, sizeof(e->share), "%s/share", e->root);
	snprintf(e->spool, sizeof(e->spool), "%s/spool", e->root);
	assert_int_equal(mkdir(e->share, 0755), 0);
	struct fscan_storage_config cfg = {.share_dir = e->share, .spool_dir = e->spool, .min_free_bytes = 1000,
					   .spool_min_free = 1000};
	assert_int_equal(fscan_storage_create(&fscan_storage_posix_ops, &cfg, &e->st), 0);
	memset(&cue_write, 0, sizeof(struct cue));
	memset(&cue_fsync, 0, sizeof(struct cue));
	memset(&cue_rename, 0, sizeof(struct cue));
	memset(&cue_unlink, 0, sizeof(struct cue));
	write_chunk = 0;
	statvfs_low_dir = NULL;
	*state = e;
	return 0;
}

static int teardown(void **state)
{
	struct env *e = *state;
	fscan_storage_destroy(e->st);
	char cmd[128];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", e->root);
	assert_int_equal(system(cmd), 0);
	free(e);
	return 0;
}

/* Entries of dir (no recursion) as "name" list count; *ret_hidden if any starts with '.'. */
static int entries(const char *dir, bool *ret_hidden)
{
	DIR *d = opendir(dir);
	if (!d)
		return -1;
	int n = 0;
	struct dirent *de;
	while ((de = readdir(d))) {
		if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
			continue;
		n++;
		if (de->d_name[0] == '.' && ret_hidden)
			*ret_hidden = true;
	}
	closedir(d);
	return n;
}

static void expect_content(const char *dir, const char *name, const char *want)
{
	char p[256], buf[256] = {0};
	snprintf(p, sizeof(p), "%s/%s", dir, name);
	FILE *f = fopen(p, "rb");
	assert_non_null(f);
	size_t n = fread(buf, 1, sizeof(buf) - 1, f);
	fclose(f);
	assert_int_equal(n, strlen(want));
	assert_memory_equal(buf, want, n);
}

/* A failing step of the share write: the temp file is gone, nothing half-written is visible,
 * and the file went to the spool instead. */
static void expect_spooled_clean(struct env *e, struct cue *c, int nth, int err)
{
	arm(c, nth, err);
	assert_int_equal(fscan_storage_put(e->st, "f.drc", "payload", 7), FSCAN_STORAGE_SPOOLED);
	bool hidden = false;
	assert_int_equal(entries(e->share, &hidden), 0);
	assert_false(hidden);
	assert_int_equal(fscan_storage_pending(e->st), 1);
	unsigned n;
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 1);
	expect_content(e->share, "f.drc", "payload");
}

static void test_write_fails_enospc(void **state)
{
	expect_spooled_clean(*state, &cue_write, 1, ENOSPC);
}

static void test_file_fsync_fails(void **state)
{
	expect_spooled_clean(*state, &cue_fsync, 1, EIO);
}

static void test_rename_fails(void **state)
{
	expect_spooled_clean(*state, &cue_rename, 1, EACCES);
}

static void test_short_writes_complete(void **state)
{
	struct env *e = *state;
	write_chunk = 3;
	assert_int_equal(fscan_storage_put(e->st, "short", "0123456789", 10), FSCAN_STORAGE_DELIVERED);
	expect_content(e->share, "short", "0123456789");
	assert_true(cue_write.calls >= 4);
}

static void test_share_low_on_space_spools(void **state)
{
	struct env *e = *state;
	statvfs_low_dir = e->share;
	assert_int_equal(fscan_storage_put(e->st, "s", "x", 1), FSCAN_STORAGE_SPOOLED);
	uint64_t free_bytes;
	assert_int_equal(fscan_storage_share_free(e->st, &free_bytes), 0);
	assert_int_equal(free_bytes, 100);
	unsigned n;
	assert_int_equal(fscan_storage_flush(e->st, &n), -ENOSPC);
	assert_int_equal(fscan_storage_pending(e->st), 1);
	statvfs_low_dir = NULL;
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	expect_content(e->share, "s", "x");
}

static void test_share_and_spool_full(void **state)
{
	struct env *e = *state;
	statvfs_low_dir = e->root; /* both */
	assert_int_equal(fscan_storage_put(e->st, "s", "x", 1), -ENOSPC);
	assert_int_equal(fscan_storage_pending(e->st), 0);
}

static void test_spool_write_fails_reports_error(void **state)
{
	struct env *e = *state;
	/* Every write fails: the share's, then the spool's. */
	arm(&cue_write, 1, EIO);
	cue_write.sticky = true;
	assert_int_equal(fscan_storage_put(e->st, "s", "x", 1), -EIO);
	bool hidden = false;
	assert_int_equal(entries(e->spool, &hidden), 0);
	assert_false(hidden);
	assert_int_equal(entries(e->share, &hidden), 0);
}

/* The crash window of delivery: the file is on the share but the spool entry survives
 * (unlink of the entry fails here as a kill -9 would leave it). The next flush delivers it
 * again: the same name with the same bytes, one file, and the entry goes. */
static void test_redelivery_after_failed_cleanup_is_idempotent(void **state)
{
	struct env *e = *state;
	statvfs_low_dir = e->share;
	assert_int_equal(fscan_storage_put(e->st, "p/scan.drc", "MESH", 4), FSCAN_STORAGE_SPOOLED);
	assert_int_equal(fscan_storage_put(e->st, "p/scan.json", "{}", 2), FSCAN_STORAGE_SPOOLED);
	statvfs_low_dir = NULL;
	arm(&cue_unlink, 1, EIO);
	unsigned n = 9;
	assert_int_equal(fscan_storage_flush(e->st, &n), -EIO);
	assert_int_equal(n, 0);
	char dir[128];
	snprintf(dir, sizeof(dir), "%s/p", e->share);
	expect_content(dir, "scan.drc", "MESH");
	assert_int_equal(fscan_storage_pending(e->st), 2);
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 2);
	bool hidden = false;
	assert_int_equal(entries(dir, &hidden), 2);
	assert_false(hidden);
	expect_content(dir, "scan.drc", "MESH");
	expect_content(dir, "scan.json", "{}");
	assert_int_equal(fscan_storage_pending(e->st), 0);
}

/* fsync of the directory fails after the rename: the (complete) file is in place but not known
 * durable, so put reports it spooled; the later delivery rewrites it identically. */
static void test_dir_fsync_fails_after_rename(void **state)
{
	struct env *e = *state;
	arm(&cue_fsync, 2, EIO); /* 1 = the file, 2 = the directory */
	assert_int_equal(fscan_storage_put(e->st, "d", "data", 4), FSCAN_STORAGE_SPOOLED);
	expect_content(e->share, "d", "data");
	unsigned n;
	assert_int_equal(fscan_storage_flush(e->st, &n), 0);
	assert_int_equal(n, 1);
	assert_int_equal(entries(e->share, NULL), 1);
	expect_content(e->share, "d", "data");
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test_setup_teardown(test_write_fails_enospc, setup, teardown),
		cmocka_unit_test_setup_teardown(test_file_fsync_fails, setup, teardown),
		cmocka_unit_test_setup_teardown(test_rename_fails, setup, teardown),
		cmocka_unit_test_setup_teardown(test_short_writes_complete, setup, teardown),
		cmocka_unit_test_setup_teardown(test_share_low_on_space_spools, setup, teardown),
		cmocka_unit_test_setup_teardown(test_share_and_spool_full, setup, teardown),
		cmocka_unit_test_setup_teardown(test_spool_write_fails_reports_error, setup, teardown),
		cmocka_unit_test_setup_teardown(test_redelivery_after_failed_cleanup_is_idempotent, setup, teardown),
		cmocka_unit_test_setup_teardown(test_dir_fsync_fails_after_rename, setup, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
