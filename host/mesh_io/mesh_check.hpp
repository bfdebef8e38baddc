// Internal to host/mesh_io: the consistency check both encoders run first.
#pragma once

#include "common/status.hpp"
#include "recon/types.hpp"

namespace facescan::mesh_io {

/// -EINVAL naming the problem when triangles index outside the vertices or a per-vertex
/// attribute has a different length than the positions.
Status check_mesh(const recon::Mesh &mesh);

} // namespace facescan::mesh_io
