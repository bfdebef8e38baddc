#pragma once
namespace facescan {
// The software version recorded in every scan's metadata: `git describe` at build time.
const char *version();
} // namespace facescan
