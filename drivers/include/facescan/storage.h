/* facescan storage driver: delivers scan files to the clinic's share, atomically, and keeps
 * them in a local spool while the share is missing or full.
 *
 * Guarantees (real backend, drivers/storage/storage_posix.c):
 *   - A reader of the share never sees a partial file: each file is written to a hidden temp
 *     file in the destination directory, fsync'ed, renamed over the final name, and the
 *     directory is fsync'ed. The temp file is unlinked on any failure.
 *   - When the share is unreachable or has less than min_free_bytes left after the write, the
 *     file goes to the spool (written just as atomically) and put() returns
 *     FSCAN_STORAGE_SPOOLED.
 *   - Spooled files are delivered by fscan_storage_flush() in the order they were put, and
 *     put() flushes first, so the share receives files in put order. Delivery is idempotent:
 *     a spool entry is removed only after its file is durably on the share, and redelivering
 *     it after a crash rewrites the same name with the same bytes — never a second copy.
 *   - Leftover temp files of a crashed process (kill -9 mid-write) are removed by create()
 *     (spool) and by each put into a directory (share).
 *
 * Every function returns 0 (or a documented positive value) or a negative errno; nothing here
 * logs or exits. One thread per handle.
 */
#ifndef FACESCAN_STORAGE_H
#define FACESCAN_STORAGE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#ifdef __cplusplus
extern "C" {
#endif

struct fscan_storage_config {
	const char *share_dir;     /* the mounted share; may be missing at times */
	const char *spool_dir;     /* local spool; created (one level) if missing */
	uint64_t min_free_bytes;   /* keep this much free on the share; 0 = 64 MiB */
	uint64_t spool_min_free;   /* refuse to spool below this free space; 0 = 64 MiB */
	mode_t file_mode;          /* mode of delivered files; 0 = 0640 */
	/* Optional: a file that must exist at the share's root for the share to count as there.
	 * An unmounted network share leaves its mount point behind as an empty local directory;
	 * without a marker, files would land on the local disk instead of being spooled. */
	const char *share_marker;
};

enum fscan_storage_result {
	FSCAN_STORAGE_DELIVERED = 0,  /* the file is on the share */
	FSCAN_STORAGE_SPOOLED = 1,    /* the file is in the spool, delivered by a later flush */
};

/* One file of a scan entry; name is one path component. */
struct fscan_storage_file {
	const char *name;
	const void *data;
	size_t len;
};

/* What fscan_storage_deliver_next() delivered. */
struct fscan_storage_delivery {
	char base[256];     /* the entry's name, "<UTC time>_<scan-id>" for the daemon */
	char scan_id[256];
	char dir[256];      /* the share folder the files went to (the patient id) */
};

typedef void (*fscan_storage_file_cb)(const char *relpath, void *ud);
typedef void (*fscan_storage_id_cb)(const char *scan_id, void *ud);

/* The backend interface. */
struct fscan_storage_ops {
	const char *name;
	int (*open)(const struct fscan_storage_config *cfg, void **ret_ctx);
	void (*close)(void *ctx);
	int (*put)(void *ctx, const char *relpath, const void *data, size_t len);
	int (*flush)(void *ctx, unsigned *ret_delivered);
	int (*pending)(void *ctx);
	int (*share_free)(void *ctx, uint64_t *ret_bytes);
	/* Scan entries (see fscan_storage_queue() and below). */
	int (*queue)(void *ctx, const char *base, const char *scan_id, const char *dir,
		     const struct fscan_storage_file *files, size_t n_files);
	int (*deliver_next)(void *ctx, struct fscan_storage_delivery *ret, fscan_storage_file_cb on_file, void *ud);
	int (*recover)(void *ctx, fscan_storage_id_cb on_failed, void *ud);
	int (*queued)(void *ctx, const char *scan_id);
	int (*scans)(void *ctx);
	int (*writable)(void *ctx);
};

extern const struct fscan_storage_ops fscan_storage_posix_ops;
extern const struct fscan_storage_ops fscan_storage_fake_ops;

struct fscan_storage;

/* Opens the spool (creating the directory if needed, sweeping stale temp files). The share
 * need not be there. -EINVAL bad config, -ENOENT/-EACCES/-ENOTDIR spool unusable. */
int fscan_storage_create(const struct fscan_storage_ops *ops, const struct fscan_storage_config *cfg,
			 struct fscan_storage **ret_storage);
void fscan_storage_destroy(struct fscan_storage *storage); /* accepts NULL */

/* Stores `len` bytes as <share>/<relpath>, creating the subdirectories of relpath.
 * relpath is relative, made of components that are non-empty, not "." or "..", free of control
 * characters, at most 255 bytes each and 1024 in all.
 * Returns FSCAN_STORAGE_DELIVERED, FSCAN_STORAGE_SPOOLED, or
 *   -EINVAL bad relpath, -ENOSPC neither share nor spool can take it, -EIO/-errno spool failed. */
int fscan_storage_put(struct fscan_storage *storage, const char *relpath, const void *data, size_t len);
/* Delivers spooled files in order until the spool is empty (0) or the share fails
 * (-ENOSPC/-ENOENT/-EIO/...: the rest stay spooled). *ret_delivered (may be NULL) counts the
 * files delivered by this call. */
int fscan_storage_flush(struct fscan_storage *storage, unsigned *ret_delivered);
/* Number of spooled files waiting, or -errno. */
int fscan_storage_pending(struct fscan_storage *storage);
/* Bytes available to us on the share (statvfs f_bavail * f_frsize); -ENOENT share missing. */
int fscan_storage_share_free(struct fscan_storage *storage, uint64_t *ret_bytes);

/* Scan entries: the spool's unit for facescand. An entry holds the files of one scan and a
 * manifest written last; it is the commit point that survives a crash. Real backend:
 * <spool>/<base>/ with its files and "manifest"; the per-file spool above lives beside it.
 *
 * Queues `n_files` files under entry `base` (one path component, sorted oldest first) for the
 * share folder `dir` (one component). Queueing the same base again replaces the entry.
 * 0, -EINVAL bad names, -ENOSPC spool below spool_min_free, -errno. */
int fscan_storage_queue(struct fscan_storage *storage, const char *base, const char *scan_id, const char *dir,
			const struct fscan_storage_file *files, size_t n_files);
/* Delivers the oldest complete entry to <share>/<dir>/<name>, each file atomically, files
 * ending in ".json" last (whoever sees the metadata sees the rest complete), then removes the
 * entry in one rename. on_file (may be NULL) gets each delivered relpath. Names are fixed per
 * entry, so a delivery repeated after a crash replaces the same files: never a second copy.
 * Returns 1 delivered (*ret filled), 0 nothing complete to deliver, -ENOENT share missing or
 * not mounted (no marker; nothing is written under it), -ENOSPC the share would keep less than
 * min_free_bytes after the whole entry, -EPROTO damaged manifest, -errno; on failure the entry
 * stays queued. */
int fscan_storage_deliver_next(struct fscan_storage *storage, struct fscan_storage_delivery *ret,
			       fscan_storage_file_cb on_file, void *ud);
/* Removes entries without a manifest (interrupted while queued) and the leftovers of a crash
 * between delivery and removal. on_failed (may be NULL) gets each interrupted entry's scan id
 * (what follows the last '_' of its base). Returns how many were interrupted, or -errno. */
int fscan_storage_recover(struct fscan_storage *storage, fscan_storage_id_cb on_failed, void *ud);
/* 1 when scan_id waits in the spool complete, 0 when not, -errno. */
int fscan_storage_queued(struct fscan_storage *storage, const char *scan_id);
/* Complete entries waiting, or -errno. */
int fscan_storage_scans(struct fscan_storage *storage);
/* Whether an entry could be queued now: a probe written atomically and removed in the spool.
 * 0, -EROFS / -EACCES / -ENOSPC / -ENOENT / -ENOTDIR ... */
int fscan_storage_writable(struct fscan_storage *storage);

/* The share-mounted guard on its own: 0 when share_dir is a directory carrying `marker` at its
 * root (marker NULL or "": the directory alone is enough), -ENOENT when either is missing (an
 * unmounted network share leaves an empty mount point without the marker), -ENOTDIR,
 * -ENAMETOOLONG, -EINVAL (a marker with '/'). */
int fscan_storage_share_present(const char *share_dir, const char *marker);
/* The atomic write itself, usable on its own: <dir>/<name> gets exactly `len` bytes or stays
 * as it was. name is one path component. Temp files left in dir by writers that no longer run
 * are removed first. 0 or -errno (temp file removed on failure). */
int fscan_write_file_atomic(const char *dir, const char *name, const void *data, size_t len, mode_t mode);
/* 0 when relpath is acceptable as documented for fscan_storage_put(), else -EINVAL. */
int fscan_storage_check_relpath(const char *relpath);

#ifdef __cplusplus
}
#endif
#endif
