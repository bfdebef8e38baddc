/* Private to drivers/storage: the handle behind struct fscan_storage. */
#ifndef FACESCAN_STORAGE_INTERNAL_H
#define FACESCAN_STORAGE_INTERNAL_H

#include "facescan/storage.h"

#define FSCAN_STORAGE_DEFAULT_MIN_FREE (64ull << 20)
#define FSCAN_STORAGE_MAX_RELPATH 1024u
#define FSCAN_STORAGE_MAX_NAME 255u

/* A scan entry's commit point, written after its files. */
#define FSCAN_STORAGE_MANIFEST "manifest"

int fscan_storage_check_name(const char *name);
/* The scan id in a base "<UTC time>_<scan-id>": what follows the last '_'. */
const char *fscan_storage_scan_id_of(const char *base);
/* Whether a file is metadata (".json"), delivered after the others. */
bool fscan_storage_is_metadata(const char *name);

struct fscan_storage {
	const struct fscan_storage_ops *ops;
	void *ctx;
};

#endif
