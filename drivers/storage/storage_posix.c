/* Real storage backend: the share and the spool are POSIX directories.
 *
 * Spool entries are files "<20-digit sequence>.spool" holding a header line
 * "FSCANSPOOL 1 <data length>\n", the relpath and "\n", then the data; each is written with the
 * same atomic write as a delivery, so an entry is either complete or absent. Delivery order is
 * the sequence order. An entry is unlinked only after its file is durably on the share; a crash
 * in between redelivers the same bytes under the same name, which replaces the file with an
 * identical one (rename is atomic): no partial file, no second copy. */
#define _GNU_SOURCE
#include "storage_atomic.h"
#include "storage_internal.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#define SPOOL_MAGIC "FSCANSPOOL 1 "
#define SPOOL_SUFFIX ".spool"

struct posix {
	char *share, *spool;
	char *marker; /* NULL = none */
	int spool_fd;
	uint64_t min_free, spool_min_free;
	mode_t mode;
	uint64_t next_seq;
};

static int free_bytes(const char *dir, uint64_t *ret)
{
	struct statvfs v;
	if (statvfs(dir, &v) < 0)
		return -errno;
	*ret = (uint64_t)v.f_bavail * (uint64_t)v.f_frsize;
	return 0;
}

/* Sequence numbers of the spool's entries, sorted. *ret_seqs is malloc'ed. */
static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

static int list_spool(struct posix *p, uint64_t **ret_seqs, size_t *ret_n)
{
	int fd = dup(p->spool_fd);
	if (fd < 0)
		return -errno;
	DIR *d = fdopendir(fd);
	if (!d) {
		int r = -errno;
		close(fd);
		return r;
	}
	rewinddir(d);
	uint64_t *v = NULL;
	size_t n = 0, cap = 0;
	int r = 0;
	struct dirent *e;
	while ((e = readdir(d))) {
		char *end;
		if (e->d_name[0] < '0' || e->d_name[0] > '9')
			continue;
		uint64_t seq = strtoull(e->d_name, &end, 10);
		if (strcmp(end, SPOOL_SUFFIX))
			continue;
		if (n == cap) {
			cap = cap ? cap * 2 : 16;
			uint64_t *nv = realloc(v, cap * sizeof(*v));
			if (!nv) {
				r = -ENOMEM;
				break;
			}
			v = nv;
		}
		v[n++] = seq;
	}
	closedir(d);
	if (r < 0) {
		free(v);
		return r;
	}
	if (n)
		qsort(v, n, sizeof(*v), cmp_u64);
	*ret_seqs = v;
	*ret_n = n;
	return 0;
}

static int posix_open(const struct fscan_storage_config *cfg, void **ret_ctx)
{
	struct posix *p = calloc(1, sizeof(*p));
	if (!p)
		return -ENOMEM;
	int r = -ENOMEM;
	p->share = strdup(cfg->share_dir);
	p->spool = strdup(cfg->spool_dir);
	if (!p->share || !p->spool)
		goto err_free;
	if (cfg->share_marker) {
		if (!*cfg->share_marker || strchr(cfg->share_marker, '/')) {
			r = -EINVAL;
			goto err_free;
		}
		if (!(p->marker = strdup(cfg->share_marker)))
			goto err_free;
	}
	p->min_free = cfg->min_free_bytes ? cfg->min_free_bytes : FSCAN_STORAGE_DEFAULT_MIN_FREE;
	p->spool_min_free = cfg->spool_min_free ? cfg->spool_min_free : FSCAN_STORAGE_DEFAULT_MIN_FREE;
	p->mode = cfg->file_mode ? cfg->file_mode : 0640;
	if (mkdir(p->spool, 0750) < 0 && errno != EEXIST) {
		r = -errno;
		goto err_free;
	}
	p->spool_fd = open(p->spool, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (p->spool_fd < 0) {
		r = -errno;
		goto err_free;
	}
	fscan_atomic_sweep(p->spool_fd);
	uint64_t *seqs = NULL;
	size_t n = 0;
	r = list_spool(p, &seqs, &n);
	if (r < 0)
		goto err_close;
	p->next_seq = n ? seqs[n - 1] + 1 : 1;
	free(seqs);
	*ret_ctx = p;
	return 0;

err_close:
	close(p->spool_fd);
err_free:
	free(p->marker);
	free(p->share);
	free(p->spool);
	free(p);
	return r;
}

static void posix_close(void *ctx)
{
	struct posix *p = ctx;
	close(p->spool_fd);
	free(p->marker);
	free(p->share);
	free(p->spool);
	free(p);
}

/* Opens (creating as needed) the directory that will hold relpath's file, under the share.
 * Returns its fd and points *ret_name at the file name inside relpath. */
static int open_parent(struct posix *p, const char *relpath, const char **ret_name)
{
	int fd = open(p->share, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0)
		return -errno;
	const char *comp = relpath;
	const char *slash;
	while ((slash = strchr(comp, '/'))) {
		char name[FSCAN_STORAGE_MAX_NAME + 1];
		size_t len = (size_t)(slash - comp);
		memcpy(name, comp, len);
		name[len] = '\0';
		bool created = mkdirat(fd, name, 0750) == 0;
		if (!created && errno != EEXIST) {
			int r = -errno;
			close(fd);
			return r;
		}
		int sub = openat(fd, name, O_RDONLY | O_DIRECTORY | O_CLOEXEC | O_NOFOLLOW);
		if (sub < 0 || (created && fsync(fd) < 0)) {
			int r = -errno;
			if (sub >= 0)
				close(sub);
			close(fd);
			return r;
		}
		close(fd);
		fd = sub;
		comp = slash + 1;
	}
	*ret_name = comp;
	return fd;
}

/* 0 when the share is there (and carries its marker, if one is configured), else -ENOENT. */
static int share_present(struct posix *p)
{
	return fscan_storage_share_present(p->share, p->marker);
}

static int deliver(struct posix *p, const char *relpath, const void *data, size_t len)
{
	uint64_t avail = 0;
	int r = share_present(p);
	if (r < 0)
		return r;
	r = free_bytes(p->share, &avail);
	if (r < 0)
		return r;
	if (avail < len || avail - len < p->min_free)
		return -ENOSPC;
	const char *name = NULL;
	int dirfd = open_parent(p, relpath, &name);
	if (dirfd < 0)
		return dirfd;
	fscan_atomic_sweep(dirfd);
	struct fscan_buf b = {data, len};
	r = fscan_atomic_write_at(dirfd, name, &b, 1, p->mode);
	close(dirfd);
	return r;
}

static int spool_entry(struct posix *p, const char *relpath, const void *data, size_t len)
{
	uint64_t avail = 0;
	int r = free_bytes(p->spool, &avail);
	if (r < 0)
		return r;
	if (avail < len || avail - len < p->spool_min_free)
		return -ENOSPC;
	char hdr[64 + FSCAN_STORAGE_MAX_RELPATH];
	int hlen = snprintf(hdr, sizeof(hdr), SPOOL_MAGIC "%zu\n%s\n", len, relpath);
	if (hlen < 0 || (size_t)hlen >= sizeof(hdr))
		return -EINVAL;
	char name[64];
	snprintf(name, sizeof(name), "%020" PRIu64 SPOOL_SUFFIX, p->next_seq);
	struct fscan_buf b[2] = {{hdr, (size_t)hlen}, {data, len}};
	r = fscan_atomic_write_at(p->spool_fd, name, b, 2, 0600);
	if (r < 0)
		return r;
	p->next_seq++;
	return 0;
}

/* Reads spool entry `seq`: *ret_buf holds the whole file, *ret_relpath and *ret_data point
 * into it. -EBADMSG when it is not a well-formed entry. */
static int read_entry(struct posix *p, uint64_t seq, char **ret_buf, const char **ret_relpath,
		      const void **ret_data, size_t *ret_len)
{
	char name[64];
	snprintf(name, sizeof(name), "%020" PRIu64 SPOOL_SUFFIX, seq);
	int fd = openat(p->spool_fd, name, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return -errno;
	struct stat st;
	int r = 0;
	char *buf = NULL;
	if (fstat(fd, &st) < 0) {
		r = -errno;
		goto out;
	}
	size_t size = (size_t)st.st_size;
	buf = malloc(size + 1);
	if (!buf) {
		r = -ENOMEM;
		goto out;
	}
	size_t got = 0;
	while (got < size) {
		ssize_t n = read(fd, buf + got, size - got);
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0) {
			r = n < 0 ? -errno : -EBADMSG;
			goto out;
		}
		got += (size_t)n;
	}
	buf[size] = '\0';
	size_t mlen = strlen(SPOOL_MAGIC);
	char *end;
	if (size < mlen || memcmp(buf, SPOOL_MAGIC, mlen)) {
		r = -EBADMSG;
		goto out;
	}
	unsigned long long dlen = strtoull(buf + mlen, &end, 10);
	if (*end != '\n') {
		r = -EBADMSG;
		goto out;
	}
	char *rel = end + 1;
	char *nl = memchr(rel, '\n', size - (size_t)(rel - buf));
	if (!nl || (size_t)(buf + size - (nl + 1)) != dlen) {
		r = -EBADMSG;
		goto out;
	}
	*nl = '\0';
	if (fscan_storage_check_relpath(rel) < 0) {
		r = -EBADMSG;
		goto out;
	}
	*ret_buf = buf;
	*ret_relpath = rel;
	*ret_data = nl + 1;
	*ret_len = (size_t)dlen;
	buf = NULL;
out:
	free(buf);
	close(fd);
	return r;
}

static int posix_flush(void *ctx, unsigned *ret_delivered)
{
	struct posix *p = ctx;
	uint64_t *seqs = NULL;
	size_t n = 0;
	int r = list_spool(p, &seqs, &n);
	if (r < 0)
		return r;
	unsigned delivered = 0;
	for (size_t i = 0; i < n; i++) {
		char name[64];
		snprintf(name, sizeof(name), "%020" PRIu64 SPOOL_SUFFIX, seqs[i]);
		char *buf = NULL;
		const char *relpath = NULL;
		const void *data = NULL;
		size_t len = 0;
		r = read_entry(p, seqs[i], &buf, &relpath, &data, &len);
		if (r == -EBADMSG) {
			/* Not ours or damaged: set it aside rather than block the queue. */
			char bad[80];
			snprintf(bad, sizeof(bad), "%s.bad", name);
			renameat(p->spool_fd, name, p->spool_fd, bad);
			r = 0;
			continue;
		}
		if (r == -ENOENT) { /* delivered by a concurrent flush */
			r = 0;
			continue;
		}
		if (r < 0)
			break;
		r = deliver(p, relpath, data, len);
		free(buf);
		if (r < 0)
			break;
		/* Durably delivered: now (and only now) the entry may go. */
		if (unlinkat(p->spool_fd, name, 0) < 0 || fsync(p->spool_fd) < 0) {
			r = -errno;
			break;
		}
		delivered++;
	}
	free(seqs);
	*ret_delivered = delivered;
	return r;
}

static int posix_pending(void *ctx)
{
	struct posix *p = ctx;
	uint64_t *seqs = NULL;
	size_t n = 0;
	int r = list_spool(p, &seqs, &n);
	if (r < 0)
		return r;
	free(seqs);
	return n > INT32_MAX ? INT32_MAX : (int)n;
}

static int posix_put(void *ctx, const char *relpath, const void *data, size_t len)
{
	struct posix *p = ctx;
	unsigned n;
	int pending = posix_pending(p);
	/* Older spooled files go first, so the share sees put order. */
	bool clear = pending == 0 || (pending > 0 && posix_flush(p, &n) == 0);
	if (clear) {
		int r = deliver(p, relpath, data, len);
		if (r == 0)
			return FSCAN_STORAGE_DELIVERED;
		if (r == -ENOMEM)
			return r;
	}
	int r = spool_entry(p, relpath, data, len);
	return r < 0 ? r : FSCAN_STORAGE_SPOOLED;
}

static int posix_share_free(void *ctx, uint64_t *ret_bytes)
{
	struct posix *p = ctx;
	int r = share_present(p);
	return r < 0 ? r : free_bytes(p->share, ret_bytes);
}

const struct fscan_storage_ops fscan_storage_posix_ops = {
	.name = "posix",
	.open = posix_open,
	.close = posix_close,
	.put = posix_put,
	.flush = posix_flush,
	.pending = posix_pending,
	.share_free = posix_share_free,
};
