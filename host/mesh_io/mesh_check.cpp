// The consistency check both encoders run first (internal to host/mesh_io).
#include "mesh_io/mesh_check.hpp"

#include <cerrno>
#include <string>

namespace facescan::mesh_io {

Status check_mesh(const recon::Mesh &mesh)
{
	const size_t n = mesh.positions.size();
	if (n == 0)
		return Status::error(-EINVAL, "mesh has no vertices");
	auto attr = [n](size_t size, const char *name) -> Status {
		if (size != 0 && size != n)
			return Status::error(-EINVAL, std::string("mesh has ") + std::to_string(size) + " " +
							      name + " for " + std::to_string(n) + " vertices");
		return {};
	};
	Status s = attr(mesh.uvs.size(), "uvs");
	if (s.ok())
		s = attr(mesh.normals.size(), "normals");
	if (s.ok())
		s = attr(mesh.colours.size(), "colours");
	if (!s.ok())
		return s;
	for (size_t t = 0; t < mesh.triangles.size(); ++t)
		for (int k = 0; k < 3; ++k) {
			const int v = mesh.triangles[t][k];
			if (v < 0 || size_t(v) >= n)
				return Status::error(-EINVAL, "triangle " + std::to_string(t) + " indexes vertex " +
								      std::to_string(v) + " of " + std::to_string(n));
		}
	return {};
}

} // namespace facescan::mesh_io
