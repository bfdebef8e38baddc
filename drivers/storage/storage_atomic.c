/* The atomic file write (after systemd's write_string_file_atomic_at): hidden temp file in the
 * destination directory -> write -> fsync -> fchmod -> close -> rename -> fsync the directory;
 * the temp file is unlinked on any failure. Kept apart from the spool logic so that tests can
 * wrap the system calls (-Wl,--wrap) under both. */
#define _GNU_SOURCE
#include "storage_atomic.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static unsigned long tmp_counter;

static int write_all(int fd, const void *data, size_t len)
{
	const uint8_t *p = data;
	while (len) {
		ssize_t n = write(fd, p, len);
		if (n < 0) {
			if (errno == EINTR)
				continue;
			return -errno;
		}
		if (n == 0)
			return -EIO;
		p += n;
		len -= (size_t)n;
	}
	return 0;
}

int fscan_atomic_write_at(int dirfd, const char *name, const struct fscan_buf *bufs, size_t n_bufs, mode_t mode)
{
	if (dirfd < 0 || !name || !*name || strchr(name, '/') || strlen(name) > 255)
		return -EINVAL;
	/* The temp name keeps a prefix of the final name for people looking at the share; the
	 * pid lets a later sweep tell a dead writer's leftovers from a live one's. */
	char tmp[300];
	snprintf(tmp, sizeof(tmp), "%s%ld.%lu.%.64s", FSCAN_TMP_PREFIX, (long)getpid(), ++tmp_counter, name);
	int fd = openat(dirfd, tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, mode & 07777);
	if (fd < 0)
		return -errno;
	int r = 0;
	for (size_t i = 0; i < n_bufs && !r; i++)
		if (bufs[i].len)
			r = write_all(fd, bufs[i].data, bufs[i].len);
	if (!r && fsync(fd) < 0)
		r = -errno;
	if (!r && fchmod(fd, mode & 07777) < 0) /* the umask must not decide who may read it */
		r = -errno;
	if (close(fd) < 0 && !r)
		r = -errno; /* network filesystems report write errors at close */
	if (r < 0)
		goto err_unlink;
	if (renameat(dirfd, tmp, dirfd, name) < 0) {
		r = -errno;
		goto err_unlink;
	}
	/* The rename is durable only once the directory is. The file is in place already, so a
	 * failure here is reported but the (complete) file stays. */
	if (fsync(dirfd) < 0)
		return -errno;
	return 0;

err_unlink:
	unlinkat(dirfd, tmp, 0);
	return r;
}

int fscan_write_file_atomic(const char *dir, const char *name, const void *data, size_t len, mode_t mode)
{
	if (!dir || (!data && len))
		return -EINVAL;
	int dirfd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (dirfd < 0)
		return -errno;
	/* Temp files of writers that died (kill -9 mid-write) go first. */
	fscan_atomic_sweep(dirfd);
	struct fscan_buf b = {data, len};
	int r = fscan_atomic_write_at(dirfd, name, &b, 1, mode ? mode : 0640);
	close(dirfd);
	return r;
}

int fscan_atomic_sweep(int dirfd)
{
	int fd = dup(dirfd);
	if (fd < 0)
		return -errno;
	DIR *d = fdopendir(fd);
	if (!d) {
		int r = -errno;
		close(fd);
		return r;
	}
	int removed = 0;
	struct dirent *e;
	size_t plen = strlen(FSCAN_TMP_PREFIX);
	while ((e = readdir(d))) {
		if (strncmp(e->d_name, FSCAN_TMP_PREFIX, plen))
			continue;
		char *end;
		long pid = strtol(e->d_name + plen, &end, 10);
		if (end == e->d_name + plen || *end != '.' || pid <= 0)
			continue;
		if (pid != (long)getpid() && kill((pid_t)pid, 0) < 0 && errno == ESRCH &&
		    unlinkat(dirfd, e->d_name, 0) == 0)
			removed++;
	}
	closedir(d);
	return removed;
}
