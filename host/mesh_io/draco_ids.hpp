// Internal to host/mesh_io: Draco encode/decode that name attributes by their unique id, as
// glTF's KHR_draco_mesh_compression maps "POSITION", "TEXCOORD_0", ... to them.
#pragma once

#include "common/status.hpp"
#include "mesh_io/mesh_io.hpp"

namespace facescan::mesh_io {

/// Unique ids of the attributes in a Draco bitstream; -1 = absent.
struct DracoAttributeIds {
	int position = -1, uv = -1, normal = -1, colour = -1;
};

/// encode_draco() that also reports the ids it gave the attributes.
Status encode_draco_ids(const recon::Mesh &mesh, const DracoOptions &options, std::vector<char> *ret_bytes,
			DracoAttributeIds *ret_ids);
/// decode_draco() taking attributes by unique id (ids == nullptr: by type, as decode_draco).
Status decode_draco_ids(const void *data, size_t size, const DracoAttributeIds *ids, recon::Mesh *ret_mesh);

} // namespace facescan::mesh_io
