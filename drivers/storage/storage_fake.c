/* Fake storage backend: an in-memory share and spool with the real backend's contract
 * (atomic files, spool when the share is missing or full, ordered idempotent delivery). */
#include "facescan/storage_fake.h"
#include "storage_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct file {
	char *relpath;
	void *data;
	size_t len;
};

struct list {
	struct file *v;
	size_t n, cap;
};

/* A scan entry; files[].relpath holds the bare file name. */
struct scan {
	char *base, *scan_id, *dir;
	struct list files;
	bool complete; /* its manifest "written" */
};

struct fake {
	struct list share, spool;
	struct scan *scans;
	size_t n_scans;
	int crash_after; /* files the next queue writes before it "dies"; -1 none */
	bool spool_writable;
	char **deliveries;
	size_t n_deliveries;
	bool online;
	uint64_t share_free;
	uint64_t min_free;
	unsigned fail_count;
	int fail_err;
};

static void file_free(struct file *f)
{
	free(f->relpath);
	free(f->data);
}

static int list_push(struct list *l, const char *relpath, const void *data, size_t len)
{
	if (l->n == l->cap) {
		size_t cap = l->cap ? l->cap * 2 : 8;
		struct file *v = realloc(l->v, cap * sizeof(*v));
		if (!v)
			return -ENOMEM;
		l->v = v;
		l->cap = cap;
	}
	struct file f = {.relpath = strdup(relpath), .data = malloc(len ? len : 1), .len = len};
	if (!f.relpath || !f.data) {
		file_free(&f);
		return -ENOMEM;
	}
	if (len)
		memcpy(f.data, data, len);
	l->v[l->n++] = f;
	return 0;
}

static struct file *list_find(struct list *l, const char *relpath)
{
	for (size_t i = 0; i < l->n; i++)
		if (!strcmp(l->v[i].relpath, relpath))
			return &l->v[i];
	return NULL;
}

static int fake_open(const struct fscan_storage_config *cfg, void **ret_ctx)
{
	struct fake *f = calloc(1, sizeof(*f));
	if (!f)
		return -ENOMEM;
	f->online = true;
	f->spool_writable = true;
	f->crash_after = -1;
	f->share_free = 1ull << 40;
	f->min_free = cfg->min_free_bytes ? cfg->min_free_bytes : FSCAN_STORAGE_DEFAULT_MIN_FREE;
	*ret_ctx = f;
	return 0;
}

static void scan_free(struct scan *s);

static void fake_close(void *ctx)
{
	struct fake *f = ctx;
	for (size_t i = 0; i < f->share.n; i++)
		file_free(&f->share.v[i]);
	for (size_t i = 0; i < f->spool.n; i++)
		file_free(&f->spool.v[i]);
	for (size_t i = 0; i < f->n_deliveries; i++)
		free(f->deliveries[i]);
	for (size_t i = 0; i < f->n_scans; i++)
		scan_free(&f->scans[i]);
	free(f->scans);
	free(f->share.v);
	free(f->spool.v);
	free(f->deliveries);
	free(f);
}

/* Writes one file to the share, replacing a file of the same name (as rename does). */
static int deliver(struct fake *f, const char *relpath, const void *data, size_t len)
{
	if (!f->online)
		return -ENOENT;
	if (f->share_free < len || f->share_free - len < f->min_free)
		return -ENOSPC;
	if (f->fail_count) {
		f->fail_count--;
		return f->fail_err;
	}
	char **d = realloc(f->deliveries, (f->n_deliveries + 1) * sizeof(*d));
	if (!d)
		return -ENOMEM;
	f->deliveries = d;
	char *name = strdup(relpath);
	if (!name)
		return -ENOMEM;
	struct file *old = list_find(&f->share, relpath);
	if (old) {
		void *copy = malloc(len ? len : 1);
		if (!copy) {
			free(name);
			return -ENOMEM;
		}
		if (len)
			memcpy(copy, data, len);
		f->share_free += old->len;
		free(old->data);
		old->data = copy;
		old->len = len;
	} else {
		int r = list_push(&f->share, relpath, data, len);
		if (r < 0) {
			free(name);
			return r;
		}
	}
	f->share_free -= len;
	f->deliveries[f->n_deliveries++] = name;
	return 0;
}

static int fake_flush(void *ctx, unsigned *ret_delivered)
{
	struct fake *f = ctx;
	unsigned n = 0;
	int r = 0;
	size_t i = 0;
	for (; i < f->spool.n; i++) {
		struct file *s = &f->spool.v[i];
		r = deliver(f, s->relpath, s->data, s->len);
		if (r < 0)
			break;
		file_free(s);
		n++;
	}
	if (i) {
		memmove(f->spool.v, f->spool.v + i, (f->spool.n - i) * sizeof(*f->spool.v));
		f->spool.n -= i;
	}
	*ret_delivered = n;
	return r;
}

static int fake_put(void *ctx, const char *relpath, const void *data, size_t len)
{
	struct fake *f = ctx;
	unsigned n;
	/* Older spooled files go first, so the share sees put order. */
	if (fake_flush(f, &n) == 0 && deliver(f, relpath, data, len) == 0)
		return FSCAN_STORAGE_DELIVERED;
	int r = list_push(&f->spool, relpath, data, len);
	return r < 0 ? r : FSCAN_STORAGE_SPOOLED;
}

static int fake_pending(void *ctx)
{
	return (int)((struct fake *)ctx)->spool.n;
}

static int fake_share_free(void *ctx, uint64_t *ret_bytes)
{
	struct fake *f = ctx;
	if (!f->online)
		return -ENOENT;
	*ret_bytes = f->share_free;
	return 0;
}

/* ---- scan entries: in memory, with the real backend's contract ---- */

static void scan_free(struct scan *s)
{
	free(s->base);
	free(s->scan_id);
	free(s->dir);
	for (size_t i = 0; i < s->files.n; i++)
		file_free(&s->files.v[i]);
	free(s->files.v);
}

static void scan_remove(struct fake *f, size_t i)
{
	scan_free(&f->scans[i]);
	memmove(f->scans + i, f->scans + i + 1, (f->n_scans - i - 1) * sizeof(*f->scans));
	f->n_scans--;
}

static int fake_queue(void *ctx, const char *base, const char *scan_id, const char *dir,
		      const struct fscan_storage_file *files, size_t n_files)
{
	struct fake *f = ctx;
	if (!f->spool_writable)
		return -EROFS;
	for (size_t i = 0; i < f->n_scans; i++)
		if (!strcmp(f->scans[i].base, base)) {
			scan_remove(f, i); /* queued again: replaces the entry */
			break;
		}
	struct scan *v = realloc(f->scans, (f->n_scans + 1) * sizeof(*v));
	if (!v)
		return -ENOMEM;
	f->scans = v;
	/* Sorted by base, as the real backend's directory listing is. */
	size_t at = 0;
	while (at < f->n_scans && strcmp(f->scans[at].base, base) < 0)
		at++;
	memmove(f->scans + at + 1, f->scans + at, (f->n_scans - at) * sizeof(*f->scans));
	f->n_scans++;
	struct scan *s = &f->scans[at];
	*s = (struct scan){.base = strdup(base), .scan_id = strdup(scan_id), .dir = strdup(dir)};
	if (!s->base || !s->scan_id || !s->dir) {
		scan_remove(f, at);
		return -ENOMEM;
	}
	for (size_t i = 0; i < n_files; i++) {
		if (f->crash_after >= 0 && (size_t)f->crash_after == i) {
			f->crash_after = -1;
			return -EINTR; /* "killed" before the manifest: the entry stays incomplete */
		}
		int r = list_push(&s->files, files[i].name, files[i].data, files[i].len);
		if (r < 0) {
			scan_remove(f, at);
			return r;
		}
	}
	if (f->crash_after >= 0) {
		f->crash_after = -1;
		return -EINTR;
	}
	s->complete = true;
	return 0;
}

static int fake_deliver_next(void *ctx, struct fscan_storage_delivery *ret, fscan_storage_file_cb on_file, void *ud)
{
	struct fake *f = ctx;
	size_t i = 0;
	while (i < f->n_scans && !f->scans[i].complete)
		i++;
	if (i == f->n_scans)
		return 0;
	struct scan *s = &f->scans[i];
	uint64_t bytes = 0;
	for (size_t k = 0; k < s->files.n; k++)
		bytes += s->files.v[k].len;
	if (!f->online)
		return -ENOENT;
	if (f->share_free < bytes || f->share_free - bytes < f->min_free)
		return -ENOSPC;
	for (int pass = 0; pass < 2; pass++)
		for (size_t k = 0; k < s->files.n; k++) {
			struct file *x = &s->files.v[k];
			if (fscan_storage_is_metadata(x->relpath) != (pass == 1))
				continue;
			char rel[2 * FSCAN_STORAGE_MAX_NAME + 2];
			snprintf(rel, sizeof(rel), "%s/%s", s->dir, x->relpath);
			int r = deliver(f, rel, x->data, x->len);
			if (r < 0)
				return r;
			if (on_file)
				on_file(rel, ud);
		}
	snprintf(ret->base, sizeof(ret->base), "%s", s->base);
	snprintf(ret->scan_id, sizeof(ret->scan_id), "%s", s->scan_id);
	snprintf(ret->dir, sizeof(ret->dir), "%s", s->dir);
	scan_remove(f, i);
	return 1;
}

static int fake_recover(void *ctx, fscan_storage_id_cb on_failed, void *ud)
{
	struct fake *f = ctx;
	int failed = 0;
	for (size_t i = 0; i < f->n_scans;) {
		if (f->scans[i].complete) {
			i++;
			continue;
		}
		if (on_failed)
			on_failed(fscan_storage_scan_id_of(f->scans[i].base), ud);
		failed++;
		scan_remove(f, i);
	}
	return failed;
}

static int fake_count(struct fake *f, const char *want_id)
{
	int n = 0;
	for (size_t i = 0; i < f->n_scans; i++)
		n += f->scans[i].complete && (!want_id || !strcmp(fscan_storage_scan_id_of(f->scans[i].base), want_id));
	return n;
}

static int fake_queued(void *ctx, const char *scan_id)
{
	return fake_count(ctx, scan_id) > 0;
}

static int fake_scans(void *ctx)
{
	return fake_count(ctx, NULL);
}

static int fake_writable(void *ctx)
{
	return ((struct fake *)ctx)->spool_writable ? 0 : -EROFS;
}

const struct fscan_storage_ops fscan_storage_fake_ops = {
	.name = "fake",
	.open = fake_open,
	.close = fake_close,
	.put = fake_put,
	.flush = fake_flush,
	.pending = fake_pending,
	.share_free = fake_share_free,
	.queue = fake_queue,
	.deliver_next = fake_deliver_next,
	.recover = fake_recover,
	.queued = fake_queued,
	.scans = fake_scans,
	.writable = fake_writable,
};

/* ---- back doors ---- */

static struct fake *fake_of(struct fscan_storage *st)
{
	return st && st->ops == &fscan_storage_fake_ops ? st->ctx : NULL;
}

int fscan_storage_fake_set_share_online(struct fscan_storage *storage, bool online)
{
	struct fake *f = fake_of(storage);
	if (!f)
		return -EINVAL;
	f->online = online;
	return 0;
}

int fscan_storage_fake_set_share_free(struct fscan_storage *storage, uint64_t bytes)
{
	struct fake *f = fake_of(storage);
	if (!f)
		return -EINVAL;
	f->share_free = bytes;
	return 0;
}

int fscan_storage_fake_fail_writes(struct fscan_storage *storage, unsigned count, int err)
{
	struct fake *f = fake_of(storage);
	if (!f || err >= 0)
		return -EINVAL;
	f->fail_count = count;
	f->fail_err = err;
	return 0;
}

int fscan_storage_fake_get(struct fscan_storage *storage, const char *relpath, const void **ret_data,
			   size_t *ret_len)
{
	struct fake *f = fake_of(storage);
	if (!f || !relpath || !ret_data || !ret_len)
		return -EINVAL;
	struct file *x = list_find(&f->share, relpath);
	if (!x)
		return -ENOENT;
	*ret_data = x->data;
	*ret_len = x->len;
	return 0;
}

int fscan_storage_fake_share_count(struct fscan_storage *storage)
{
	struct fake *f = fake_of(storage);
	return f ? (int)f->share.n : -EINVAL;
}

const char *fscan_storage_fake_delivery(struct fscan_storage *storage, unsigned n)
{
	struct fake *f = fake_of(storage);
	if (!f || n >= f->n_deliveries)
		return NULL;
	return f->deliveries[n];
}

int fscan_storage_fake_crash_next_queue(struct fscan_storage *storage, unsigned files)
{
	struct fake *f = fake_of(storage);
	if (!f || files > INT32_MAX)
		return -EINVAL;
	f->crash_after = (int)files;
	return 0;
}

int fscan_storage_fake_set_spool_writable(struct fscan_storage *storage, bool writable)
{
	struct fake *f = fake_of(storage);
	if (!f)
		return -EINVAL;
	f->spool_writable = writable;
	return 0;
}
