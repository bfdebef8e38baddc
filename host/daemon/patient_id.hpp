// Patient IDs become a directory name on the clinic share, so they are checked before use.
#pragma once

#include "common/status.hpp"

#include <string>

namespace facescan::daemon {

constexpr size_t kPatientIdMax = 64;

/// Accepts 1..kPatientIdMax characters of [A-Za-z0-9._-], not starting with '.', without "..".
/// Refused with -EINVAL and a reason that never repeats the ID (it is patient data): empty, too
/// long, path separator, "..", leading '.', control character, any other character.
Status validate_patient_id(const std::string &id);

} // namespace facescan::daemon
