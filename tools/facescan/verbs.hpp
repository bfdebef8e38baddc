// The verbs of the facescan CLI. Each verb lives in tools/<verb>/ (or beside the component it
// drives), parses its own arguments with getopt_long, prints its own --help, and returns the
// process exit code: 0 on success, 1 on a failure it has reported, 2 on bad arguments.
#pragma once

namespace facescan::cli {

using VerbMain = int (*)(int argc, char **argv);

struct Verb {
	const char *name;
	const char *summary;
	VerbMain main;
};

} // namespace facescan::cli
