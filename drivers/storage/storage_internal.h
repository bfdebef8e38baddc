/* Private to drivers/storage: the handle behind struct fscan_storage. */
#ifndef FACESCAN_STORAGE_INTERNAL_H
#define FACESCAN_STORAGE_INTERNAL_H

#include "facescan/storage.h"

#define FSCAN_STORAGE_DEFAULT_MIN_FREE (64ull << 20)
#define FSCAN_STORAGE_MAX_RELPATH 1024u
#define FSCAN_STORAGE_MAX_NAME 255u

struct fscan_storage {
	const struct fscan_storage_ops *ops;
	void *ctx;
};

#endif
