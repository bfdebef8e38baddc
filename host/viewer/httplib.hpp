// Internal to host/viewer: the one way to include cpp-httplib. Debian builds libcpp-httplib.so
// with these features (its pkg-config Cflags); the header must see the same, or the class
// layouts disagree with the library.
#pragma once

#define CPPHTTPLIB_OPENSSL_SUPPORT
#define CPPHTTPLIB_ZLIB_SUPPORT
#define CPPHTTPLIB_BROTLI_SUPPORT
#include <httplib.h>
