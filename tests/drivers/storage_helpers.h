/* Helpers of the storage driver tests (test_storage, test_storage_scan): one copy. */
#ifndef FACESCAN_TESTS_STORAGE_HELPERS_H
#define FACESCAN_TESTS_STORAGE_HELPERS_H

#include <dirent.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static void rm_rf(const char *path)
{
	char cmd[256];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", path);
	assert_int_equal(system(cmd), 0);
}

/* Files (any depth, hidden ones included) under dir. */
static int count_files(const char *dir, bool *ret_hidden)
{
	DIR *d = opendir(dir);
	if (!d)
		return 0;
	int n = 0;
	struct dirent *de;
	while ((de = readdir(d))) {
		if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
			continue;
		char p[512];
		snprintf(p, sizeof(p), "%s/%s", dir, de->d_name);
		struct stat st;
		if (stat(p, &st) == 0 && S_ISDIR(st.st_mode)) {
			n += count_files(p, ret_hidden);
		} else {
			n++;
			if (de->d_name[0] == '.' && ret_hidden)
				*ret_hidden = true;
		}
	}
	closedir(d);
	return n;
}

#endif
