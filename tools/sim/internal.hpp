// Private to tools/sim: helpers shared by the simulator's source files.
#pragma once

#include "sim/sim.hpp"

#include <cstdint>
#include <string>
#include <vector>

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

/// Surface nets over a sampled field f (negative inside; f[(k * ny + j) * nx + i] at
/// lo + h * (i, j, k)): one vertex per cell with a sign change, at the mean of its edge
/// crossings, and two triangles per grid edge with a sign change. Vertices and triangles only;
/// the winding is orient_outwards' to fix once the normals are there.
void surface_nets(const std::vector<float> &f, int nx, int ny, int nz, const cv::Vec3f &lo, float h,
		  Mesh *ret_mesh);
/// Flips every triangle whose winding disagrees with its vertices' normals.
void orient_outwards(Mesh *mesh);
/// Keeps the connected piece with the most triangles (vertices renumbered).
void keep_largest_piece(Mesh *mesh);

/// A scanned head's volume placed in the head frame (scan_head.cpp): Hounsfield units, lightly
/// smoothed, on a grid whose index axes map to head axes by x = ox - i sx, y = oy + k sz,
/// z = oz + j sy (a proper rotation of the CT's axes: columns to the subject's left, rows
/// towards the face, slices up).
struct ScanVolume {
	int nx = 0, ny = 0, nz = 0;
	cv::Vec3f spacing{1, 1, 1}, origin{0, 0, 0}; // sx sy sz; ox oy oz
	std::vector<float> hu;			      // x fastest
	cv::Vec3f lo{0, 0, 0}, hi{0, 0, 0};	      // the volume's box in the head frame
};
/// Reads DIR/volume.txt ("nx ny nz sx sy sz") and DIR/volume.raw (int16 little-endian), as
/// tools/install-web-deps.sh scan writes them, and places the nose tip on the canonical head's.
/// -ENOENT (the message says how to fetch it) when DIR has no volume, -EINVAL when malformed.
Status load_scan_volume(const std::string &dir, ScanVolume *ret_volume);
/// The skin's field at a head-frame point: negative inside (above -400 HU), air outside the volume.
float scan_field(const ScanVolume &volume, const cv::Vec3f &p);

/// A standard normal sample (Box-Muller over two counter draws).
double gaussian(uint64_t key, uint64_t index);

} // namespace facescan::sim::internal
