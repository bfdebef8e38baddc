/* Common part of the storage driver: argument checks and the relpath rule. */
#include "storage_internal.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int fscan_storage_check_relpath(const char *relpath)
{
	if (!relpath || !*relpath || relpath[0] == '/')
		return -EINVAL;
	size_t total = strlen(relpath);
	if (total > FSCAN_STORAGE_MAX_RELPATH)
		return -EINVAL;
	const char *p = relpath;
	while (*p) {
		const char *end = strchr(p, '/');
		size_t n = end ? (size_t)(end - p) : strlen(p);
		if (n == 0 || n > FSCAN_STORAGE_MAX_NAME)
			return -EINVAL;
		if ((n == 1 && p[0] == '.') || (n == 2 && p[0] == '.' && p[1] == '.'))
			return -EINVAL;
		for (size_t i = 0; i < n; i++)
			if ((unsigned char)p[i] < 0x20 || p[i] == 0x7f)
				return -EINVAL;
		if (!end)
			break;
		p = end + 1;
		if (!*p) /* trailing slash: no file name */
			return -EINVAL;
	}
	return 0;
}

int fscan_storage_create(const struct fscan_storage_ops *ops, const struct fscan_storage_config *cfg,
			 struct fscan_storage **ret_storage)
{
	if (!ops || !cfg || !ret_storage || !cfg->share_dir || !cfg->spool_dir || !*cfg->share_dir ||
	    !*cfg->spool_dir)
		return -EINVAL;
	struct fscan_storage *st = calloc(1, sizeof(*st));
	if (!st)
		return -ENOMEM;
	st->ops = ops;
	int r = ops->open(cfg, &st->ctx);
	if (r < 0) {
		free(st);
		return r;
	}
	*ret_storage = st;
	return 0;
}

void fscan_storage_destroy(struct fscan_storage *storage)
{
	if (!storage)
		return;
	storage->ops->close(storage->ctx);
	free(storage);
}

int fscan_storage_put(struct fscan_storage *storage, const char *relpath, const void *data, size_t len)
{
	if (!storage || (!data && len))
		return -EINVAL;
	int r = fscan_storage_check_relpath(relpath);
	if (r < 0)
		return r;
	return storage->ops->put(storage->ctx, relpath, data, len);
}

int fscan_storage_flush(struct fscan_storage *storage, unsigned *ret_delivered)
{
	if (!storage)
		return -EINVAL;
	unsigned n = 0;
	int r = storage->ops->flush(storage->ctx, &n);
	if (ret_delivered)
		*ret_delivered = n;
	return r;
}

int fscan_storage_pending(struct fscan_storage *storage)
{
	return storage ? storage->ops->pending(storage->ctx) : -EINVAL;
}

int fscan_storage_share_free(struct fscan_storage *storage, uint64_t *ret_bytes)
{
	if (!storage || !ret_bytes)
		return -EINVAL;
	return storage->ops->share_free(storage->ctx, ret_bytes);
}

int fscan_storage_share_present(const char *share_dir, const char *marker)
{
	struct stat st;
	if (!share_dir)
		return -EINVAL;
	if (stat(share_dir, &st) < 0)
		return -errno;
	if (!S_ISDIR(st.st_mode))
		return -ENOTDIR;
	if (!marker || !*marker)
		return 0;
	if (strchr(marker, '/'))
		return -EINVAL;
	char path[PATH_MAX];
	int n = snprintf(path, sizeof(path), "%s/%s", share_dir, marker);
	if (n < 0 || (size_t)n >= sizeof(path))
		return -ENAMETOOLONG;
	return access(path, F_OK) == 0 ? 0 : -ENOENT;
}

/* One path component: a relpath without '/'. */
int fscan_storage_check_name(const char *name)
{
	if (!name || strchr(name, '/') || strlen(name) > FSCAN_STORAGE_MAX_NAME)
		return -EINVAL;
	return fscan_storage_check_relpath(name);
}

int fscan_storage_queue(struct fscan_storage *storage, const char *base, const char *scan_id, const char *dir,
			const struct fscan_storage_file *files, size_t n_files)
{
	if (!storage || (!files && n_files) || fscan_storage_check_name(base) < 0 || base[0] == '.' ||
	    fscan_storage_check_name(scan_id) < 0 || fscan_storage_check_name(dir) < 0)
		return -EINVAL;
	for (size_t i = 0; i < n_files; i++)
		if (fscan_storage_check_name(files[i].name) < 0 || (!files[i].data && files[i].len) ||
		    !strcmp(files[i].name, FSCAN_STORAGE_MANIFEST))
			return -EINVAL;
	return storage->ops->queue(storage->ctx, base, scan_id, dir, files, n_files);
}

int fscan_storage_deliver_next(struct fscan_storage *storage, struct fscan_storage_delivery *ret,
			       fscan_storage_file_cb on_file, void *ud)
{
	if (!storage || !ret)
		return -EINVAL;
	return storage->ops->deliver_next(storage->ctx, ret, on_file, ud);
}

int fscan_storage_recover(struct fscan_storage *storage, fscan_storage_id_cb on_failed, void *ud)
{
	return storage ? storage->ops->recover(storage->ctx, on_failed, ud) : -EINVAL;
}

int fscan_storage_queued(struct fscan_storage *storage, const char *scan_id)
{
	if (!storage || fscan_storage_check_name(scan_id) < 0)
		return -EINVAL;
	return storage->ops->queued(storage->ctx, scan_id);
}

int fscan_storage_scans(struct fscan_storage *storage)
{
	return storage ? storage->ops->scans(storage->ctx) : -EINVAL;
}

int fscan_storage_writable(struct fscan_storage *storage)
{
	return storage ? storage->ops->writable(storage->ctx) : -EINVAL;
}

const char *fscan_storage_scan_id_of(const char *base)
{
	const char *us = strrchr(base, '_');
	return us ? us + 1 : base;
}

/* Non-.json files first, in their order, then the .json ones: metadata last. */
bool fscan_storage_is_metadata(const char *name)
{
	size_t n = strlen(name);
	return n >= 5 && !strcmp(name + n - 5, ".json");
}
