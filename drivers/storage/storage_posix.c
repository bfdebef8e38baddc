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
#include <time.h>
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

static int open_dir_at(int dirfd, const char *name)
{
	int fd = openat(dirfd, name, O_RDONLY | O_DIRECTORY | O_CLOEXEC | O_NOFOLLOW);
	return fd < 0 ? -errno : fd;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

static void free_names(char **v, size_t n)
{
	for (size_t i = 0; i < n; i++)
		free(v[i]);
	free(v);
}

/* Names in dirfd, sorted; with dirs_only, only directories. *ret_names is malloc'ed. */
static int list_names(int dirfd, bool dirs_only, char ***ret_names, size_t *ret_n)
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
	rewinddir(d);
	char **v = NULL;
	size_t n = 0, cap = 0;
	int r = 0;
	struct dirent *e;
	while ((e = readdir(d))) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		struct stat st;
		if (dirs_only && (fstatat(dirfd, e->d_name, &st, AT_SYMLINK_NOFOLLOW) < 0 || !S_ISDIR(st.st_mode)))
			continue;
		if (n == cap) {
			cap = cap ? cap * 2 : 16;
			char **nv = realloc(v, cap * sizeof(*v));
			if (!nv) {
				r = -ENOMEM;
				break;
			}
			v = nv;
		}
		if (!(v[n] = strdup(e->d_name))) {
			r = -ENOMEM;
			break;
		}
		n++;
	}
	closedir(d);
	if (r < 0) {
		free_names(v, n);
		return r;
	}
	if (n)
		qsort(v, n, sizeof(*v), cmp_str);
	*ret_names = v;
	*ret_n = n;
	return 0;
}

static int remove_tree_at(int dirfd, const char *name)
{
	int fd = open_dir_at(dirfd, name);
	if (fd == -ENOENT)
		return 0;
	if (fd < 0)
		return fd;
	char **v = NULL;
	size_t n = 0;
	int r = list_names(fd, false, &v, &n);
	for (size_t i = 0; r == 0 && i < n; i++)
		if (unlinkat(fd, v[i], 0) < 0 && errno != ENOENT)
			r = -errno;
	free_names(v, n);
	close(fd);
	if (r == 0 && unlinkat(dirfd, name, AT_REMOVEDIR) < 0 && errno != ENOENT)
		r = -errno;
	return r;
}

static int read_all_at(int dirfd, const char *name, char **ret_buf, size_t *ret_len)
{
	int fd = openat(dirfd, name, O_RDONLY | O_CLOEXEC);
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
	if (!(buf = malloc(size + 1))) {
		r = -ENOMEM;
		goto out;
	}
	size_t got = 0;
	while (got < size) {
		ssize_t n = read(fd, buf + got, size - got);
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0) {
			r = n < 0 ? -errno : -EIO;
			goto out;
		}
		got += (size_t)n;
	}
	buf[size] = '\0';
	*ret_buf = buf;
	*ret_len = size;
	buf = NULL;
out:
	free(buf);
	close(fd);
	return r;
}

/* Sequence numbers of the spool's entries, sorted. *ret_seqs is malloc'ed. */
static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

static int list_spool(struct posix *p, uint64_t **ret_seqs, size_t *ret_n)
{
	char **names = NULL;
	size_t n_names = 0;
	int r = list_names(p->spool_fd, false, &names, &n_names);
	if (r < 0)
		return r;
	uint64_t *v = calloc(n_names ? n_names : 1, sizeof(*v));
	size_t n = 0;
	for (size_t i = 0; v && i < n_names; i++) {
		char *end;
		if (names[i][0] < '0' || names[i][0] > '9')
			continue;
		uint64_t seq = strtoull(names[i], &end, 10);
		if (!strcmp(end, SPOOL_SUFFIX))
			v[n++] = seq;
	}
	free_names(names, n_names);
	if (!v)
		return -ENOMEM;
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
	char *buf = NULL;
	size_t size = 0;
	int r = read_all_at(p->spool_fd, name, &buf, &size);
	if (r == -EIO)
		r = -EBADMSG; /* shorter than its size said */
	if (r < 0)
		return r;
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

/* ---- scan entries: <spool>/<base>/ holding the files and "manifest" ----
 * The manifest is "FSCANSCAN 1\n<scan-id>\n<dir>\n" and one file name per line. These
 * functions open the spool by path on every call: a spool directory replaced under a running
 * daemon is seen as it is now, not through a stale descriptor. */
#define SCAN_MAGIC "FSCANSCAN 1\n"
#define DONE_PREFIX ".done-"

struct manifest {
	char *buf;             /* owns the strings below */
	const char *scan_id, *dir;
	const char **names;
	size_t n_names;
};

static void manifest_free(struct manifest *m)
{
	free(m->buf);
	free(m->names);
}

/* Reads <entry>/manifest: -ENOENT none (interrupted, or being written), -EPROTO damaged. */
static int manifest_read(int entry_fd, struct manifest *ret)
{
	struct manifest m = {0};
	size_t len = 0;
	int r = read_all_at(entry_fd, FSCAN_STORAGE_MANIFEST, &m.buf, &len);
	if (r < 0)
		return r;
	size_t ml = strlen(SCAN_MAGIC);
	if (len < ml || memcmp(m.buf, SCAN_MAGIC, ml) || m.buf[len - 1] != '\n') {
		free(m.buf);
		return -EPROTO;
	}
	size_t lines = 0;
	for (size_t i = ml; i < len; i++)
		lines += m.buf[i] == '\n';
	if (lines < 2 || !(m.names = calloc(lines, sizeof(*m.names)))) {
		r = lines < 2 ? -EPROTO : -ENOMEM;
		manifest_free(&m);
		return r;
	}
	char *p = m.buf + ml;
	for (size_t k = 0; k < lines; k++) {
		char *nl = strchr(p, '\n');
		*nl = '\0';
		if (fscan_storage_check_name(p) < 0) {
			manifest_free(&m);
			return -EPROTO;
		}
		if (k == 0)
			m.scan_id = p;
		else if (k == 1)
			m.dir = p;
		else
			m.names[m.n_names++] = p;
		p = nl + 1;
	}
	*ret = m;
	return 0;
}

static int posix_queue(void *ctx, const char *base, const char *scan_id, const char *dir,
		       const struct fscan_storage_file *files, size_t n_files)
{
	struct posix *p = ctx;
	uint64_t avail = 0, bytes = 0;
	for (size_t i = 0; i < n_files; i++)
		bytes += files[i].len;
	int r = free_bytes(p->spool, &avail);
	if (r < 0)
		return r;
	if (avail < bytes || avail - bytes < p->spool_min_free)
		return -ENOSPC;
	int spool = open_dir_at(AT_FDCWD, p->spool);
	if (spool < 0)
		return spool;
	char *man = NULL;
	int fd = -1;
	if (mkdirat(spool, base, 0750) < 0 && errno != EEXIST) {
		r = -errno;
		goto out;
	}
	if ((fd = open_dir_at(spool, base)) < 0) {
		r = fd;
		goto out;
	}
	fscan_atomic_sweep(fd);
	/* Queued again: the old manifest goes first, so a crash now reads as interrupted. */
	if (unlinkat(fd, FSCAN_STORAGE_MANIFEST, 0) < 0 && errno != ENOENT) {
		r = -errno;
		goto out;
	}
	size_t mlen = strlen(SCAN_MAGIC) + strlen(scan_id) + strlen(dir) + 2;
	for (size_t i = 0; i < n_files; i++) {
		struct fscan_buf b = {files[i].data, files[i].len};
		r = fscan_atomic_write_at(fd, files[i].name, &b, 1, p->mode);
		if (r < 0)
			goto out;
		mlen += strlen(files[i].name) + 1;
	}
	if (!(man = malloc(mlen + 1))) {
		r = -ENOMEM;
		goto out;
	}
	char *w = man + sprintf(man, SCAN_MAGIC "%s\n%s\n", scan_id, dir);
	for (size_t i = 0; i < n_files; i++)
		w += sprintf(w, "%s\n", files[i].name);
	struct fscan_buf b = {man, (size_t)(w - man)};
	r = fscan_atomic_write_at(fd, FSCAN_STORAGE_MANIFEST, &b, 1, 0640);
	if (r == 0 && fsync(spool) < 0)
		r = -errno;
out:
	free(man);
	if (fd >= 0)
		close(fd);
	close(spool);
	return r;
}

/* The spool's entries (directories, sorted) and the spool's fd, which the caller closes with
 * free_names() after walking them. On failure *ret_spool is negative and so is the result. */
static int open_entries(struct posix *p, int *ret_spool, char ***ret_names, size_t *ret_n)
{
	*ret_spool = open_dir_at(AT_FDCWD, p->spool);
	if (*ret_spool < 0)
		return *ret_spool;
	return list_names(*ret_spool, true, ret_names, ret_n);
}

/* Complete entries (a manifest present) in order; with want_id, only those of that scan. */
static int count_complete(struct posix *p, const char *want_id)
{
	int spool;
	char **v = NULL;
	size_t n = 0;
	int r = open_entries(p, &spool, &v, &n);
	if (spool < 0)
		return r;
	int count = 0;
	for (size_t i = 0; r == 0 && i < n; i++) {
		if (v[i][0] == '.' || (want_id && strcmp(fscan_storage_scan_id_of(v[i]), want_id)))
			continue;
		int fd = open_dir_at(spool, v[i]);
		if (fd >= 0 && faccessat(fd, FSCAN_STORAGE_MANIFEST, F_OK, 0) == 0)
			count++;
		if (fd >= 0)
			close(fd);
	}
	free_names(v, n);
	close(spool);
	return r < 0 ? r : count;
}

static int posix_scans(void *ctx)
{
	return count_complete(ctx, NULL);
}

static int posix_queued(void *ctx, const char *scan_id)
{
	int r = count_complete(ctx, scan_id);
	return r < 0 ? r : r > 0;
}

static int deliver_entry(struct posix *p, int spool, const char *base, struct fscan_storage_delivery *ret,
			 fscan_storage_file_cb on_file, void *ud)
{
	int fd = open_dir_at(spool, base);
	if (fd < 0)
		return fd;
	struct manifest m = {0};
	int r = manifest_read(fd, &m);
	if (r < 0) {
		close(fd);
		return r == -ENOENT ? 0 : r; /* no manifest: being written, or left for recover */
	}
	char **data = calloc(m.n_names ? m.n_names : 1, sizeof(*data));
	size_t *lens = calloc(m.n_names ? m.n_names : 1, sizeof(*lens));
	uint64_t bytes = 0, avail = 0;
	if (!data || !lens) {
		r = -ENOMEM;
		goto out;
	}
	for (size_t i = 0; i < m.n_names; i++) {
		r = read_all_at(fd, m.names[i], &data[i], &lens[i]);
		if (r < 0)
			goto out;
		bytes += lens[i];
	}
	/* The guard first: under an unmounted share's mount point nothing is written. */
	r = share_present(p);
	if (r == 0)
		r = free_bytes(p->share, &avail);
	if (r == 0 && (avail < bytes || avail - bytes < p->min_free))
		r = -ENOSPC;
	for (int pass = 0; r == 0 && pass < 2; pass++)
		for (size_t i = 0; r == 0 && i < m.n_names; i++) {
			if (fscan_storage_is_metadata(m.names[i]) != (pass == 1))
				continue;
			char rel[2 * FSCAN_STORAGE_MAX_NAME + 2];
			snprintf(rel, sizeof(rel), "%s/%s", m.dir, m.names[i]);
			r = deliver(p, rel, data[i], lens[i]);
			if (r == 0 && on_file)
				on_file(rel, ud);
		}
	if (r < 0)
		goto out;
	/* Out of the queue in one rename; a crash before the removal leaves a hidden .done- folder
	 * that recover() clears, never a half entry that would look interrupted. */
	char done[FSCAN_STORAGE_MAX_NAME + sizeof(DONE_PREFIX)];
	snprintf(done, sizeof(done), DONE_PREFIX "%s", base);
	if (renameat(spool, base, spool, done) < 0 || fsync(spool) < 0) {
		r = -errno;
		goto out;
	}
	r = remove_tree_at(spool, done);
	if (r < 0)
		goto out;
	snprintf(ret->base, sizeof(ret->base), "%s", base);
	snprintf(ret->scan_id, sizeof(ret->scan_id), "%s", m.scan_id);
	snprintf(ret->dir, sizeof(ret->dir), "%s", m.dir);
	r = 1;
out:
	for (size_t i = 0; data && i < m.n_names; i++)
		free(data[i]);
	free(data);
	free(lens);
	manifest_free(&m);
	close(fd);
	return r;
}

static int posix_deliver_next(void *ctx, struct fscan_storage_delivery *ret, fscan_storage_file_cb on_file,
			      void *ud)
{
	struct posix *p = ctx;
	int spool;
	char **v = NULL;
	size_t n = 0;
	int r = open_entries(p, &spool, &v, &n);
	if (spool < 0)
		return r;
	for (size_t i = 0; r == 0 && i < n; i++)
		if (v[i][0] != '.')
			r = deliver_entry(p, spool, v[i], ret, on_file, ud);
	free_names(v, n);
	close(spool);
	return r;
}

static int posix_recover(void *ctx, fscan_storage_id_cb on_failed, void *ud)
{
	struct posix *p = ctx;
	int spool;
	char **v = NULL;
	size_t n = 0;
	int r = open_entries(p, &spool, &v, &n);
	if (spool < 0)
		return r;
	int failed = 0;
	for (size_t i = 0; r == 0 && i < n; i++) {
		if (!strncmp(v[i], DONE_PREFIX, strlen(DONE_PREFIX))) {
			r = remove_tree_at(spool, v[i]);
			continue;
		}
		if (v[i][0] == '.')
			continue;
		int fd = open_dir_at(spool, v[i]);
		if (fd < 0) {
			r = fd;
			break;
		}
		/* "manifest.json": an entry of facescand's spool before it moved here. Kept, not
		 * reported failed: it is a complete scan this version does not deliver. */
		bool complete = faccessat(fd, FSCAN_STORAGE_MANIFEST, F_OK, 0) == 0 ||
				faccessat(fd, "manifest.json", F_OK, 0) == 0;
		close(fd);
		if (complete)
			continue;
		if (on_failed)
			on_failed(fscan_storage_scan_id_of(v[i]), ud);
		failed++;
		r = remove_tree_at(spool, v[i]);
	}
	free_names(v, n);
	close(spool);
	return r < 0 ? r : failed;
}

static int posix_writable(void *ctx)
{
	struct posix *p = ctx;
	int spool = open_dir_at(AT_FDCWD, p->spool);
	if (spool < 0)
		return spool == -ELOOP ? -ENOTDIR : spool;
	struct fscan_buf b = {"", 0};
	int r = fscan_atomic_write_at(spool, ".probe", &b, 1, 0600);
	if (r == 0)
		unlinkat(spool, ".probe", 0);
	close(spool);
	return r;
}

const struct fscan_storage_ops fscan_storage_posix_ops = {
	.name = "posix",
	.open = posix_open,
	.close = posix_close,
	.put = posix_put,
	.flush = posix_flush,
	.pending = posix_pending,
	.share_free = posix_share_free,
	.queue = posix_queue,
	.deliver_next = posix_deliver_next,
	.recover = posix_recover,
	.queued = posix_queued,
	.scans = posix_scans,
	.writable = posix_writable,
};
