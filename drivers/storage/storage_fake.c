/* Fake storage backend: an in-memory share and spool with the real backend's contract
 * (atomic files, spool when the share is missing or full, ordered idempotent delivery). */
#include "facescan/storage_fake.h"
#include "storage_internal.h"

#include <errno.h>
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

struct fake {
	struct list share, spool;
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
	f->share_free = 1ull << 40;
	f->min_free = cfg->min_free_bytes ? cfg->min_free_bytes : FSCAN_STORAGE_DEFAULT_MIN_FREE;
	*ret_ctx = f;
	return 0;
}

static void fake_close(void *ctx)
{
	struct fake *f = ctx;
	for (size_t i = 0; i < f->share.n; i++)
		file_free(&f->share.v[i]);
	for (size_t i = 0; i < f->spool.n; i++)
		file_free(&f->spool.v[i]);
	for (size_t i = 0; i < f->n_deliveries; i++)
		free(f->deliveries[i]);
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

const struct fscan_storage_ops fscan_storage_fake_ops = {
	.name = "fake",
	.open = fake_open,
	.close = fake_close,
	.put = fake_put,
	.flush = fake_flush,
	.pending = fake_pending,
	.share_free = fake_share_free,
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
