/* Private to drivers/storage: the atomic write and the sweep of dead writers' temp files. */
#ifndef FACESCAN_STORAGE_ATOMIC_H
#define FACESCAN_STORAGE_ATOMIC_H

#include "facescan/storage.h"

/* Hidden, and recognisable by the sweep: ".fscan-tmp.<pid>.<n>.<name>". */
#define FSCAN_TMP_PREFIX ".fscan-tmp."

struct fscan_buf {
	const void *data;
	size_t len;
};

/* Writes the concatenation of bufs as dirfd/name atomically. 0 or -errno. */
int fscan_atomic_write_at(int dirfd, const char *name, const struct fscan_buf *bufs, size_t n_bufs, mode_t mode);
/* Removes temp files in dirfd left by processes that no longer exist. Returns how many. */
int fscan_atomic_sweep(int dirfd);

#endif
