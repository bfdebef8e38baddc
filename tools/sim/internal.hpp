// Private to tools/sim: helpers shared by the simulator's source files.
#pragma once

#include "sim/sim.hpp"

#include <cstdint>

namespace facescan::sim::internal {

/// -EINVAL when a mesh's indices or per-vertex arrays are inconsistent (`what` names it).
Status check_mesh(const Mesh &mesh, const std::string &what);

/// Counter-based random numbers: the same (key, index) always gives the same value, so noise
/// does not depend on the thread count or the order in which pixels are rendered.
uint64_t mix64(uint64_t x);
inline double uniform01(uint64_t key, uint64_t index)
{
	return (double(mix64(key ^ mix64(index)) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}
/// The head's rotation in a scene: yaw about +y, then pitch about +x, after a roll about +z.
cv::Matx33d head_rotation(double yaw_deg, double pitch_deg, double roll_deg);

/// A standard normal sample (Box-Muller over two counter draws).
double gaussian(uint64_t key, uint64_t index);

} // namespace facescan::sim::internal
