#include "common/version.hpp"

#ifndef FACESCAN_VERSION
#define FACESCAN_VERSION "0.1.0"
#endif

const char *facescan::version()
{
	return FACESCAN_VERSION;
}
