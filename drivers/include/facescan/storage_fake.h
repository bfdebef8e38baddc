/* Back doors of the fake storage backend (fscan_storage_fake_ops): an in-memory share and spool
 * with the same contract as the real one (ordered, idempotent delivery), for daemon tests.
 * Every function takes a handle created with fscan_storage_fake_ops (-EINVAL otherwise).
 */
#ifndef FACESCAN_STORAGE_FAKE_H
#define FACESCAN_STORAGE_FAKE_H

#include "facescan/storage.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Share mounted (default) or missing: puts spool, flush fails with -ENOENT. */
int fscan_storage_fake_set_share_online(struct fscan_storage *storage, bool online);
/* Free bytes on the share (default 1 TiB); each delivery subtracts its size. */
int fscan_storage_fake_set_share_free(struct fscan_storage *storage, uint64_t bytes);
/* The next `count` writes to the share fail with `err` (negative errno, e.g. -EIO). */
int fscan_storage_fake_fail_writes(struct fscan_storage *storage, unsigned count, int err);
/* A delivered file: 0 and *ret_data / *ret_len point into the fake (valid until the next
 * call on the handle), -ENOENT when no such file is on the share. */
int fscan_storage_fake_get(struct fscan_storage *storage, const char *relpath, const void **ret_data,
			   size_t *ret_len);
/* Number of files on the share. */
int fscan_storage_fake_share_count(struct fscan_storage *storage);
/* The relpath of the n-th delivery (0 = first) in the order it reached the share, or NULL. */
const char *fscan_storage_fake_delivery(struct fscan_storage *storage, unsigned n);

/* The next fscan_storage_queue() stops after `files` files, as a process killed mid-spool
 * would: the entry stays without its manifest and the call returns -EINTR. */
int fscan_storage_fake_crash_next_queue(struct fscan_storage *storage, unsigned files);
/* Spool writable (default) or not: queue and writable() fail with -EROFS. */
int fscan_storage_fake_set_spool_writable(struct fscan_storage *storage, bool writable);

#ifdef __cplusplus
}
#endif
#endif
