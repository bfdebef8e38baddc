// The fuzz harnesses' invariant check: a broken invariant aborts, which libFuzzer reports as a
// crash with the input that caused it (assert would vanish under -DNDEBUG).
#pragma once

#include <cstdio>
#include <cstdlib>

#define CHECK(cond)                                                                                \
	do {                                                                                       \
		if (!(cond)) {                                                                     \
			std::fprintf(stderr, "invariant failed: %s (%s:%d)\n", #cond, __FILE__, __LINE__); \
			std::abort();                                                              \
		}                                                                                  \
	} while (0)
