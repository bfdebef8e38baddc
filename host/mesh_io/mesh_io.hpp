// Mesh files: Draco (the product's output) and PLY (for inspection, ground truth, convert).
// Encoders and decoders work on bytes in memory; the write_* helpers add the atomic file write
// (temp file + rename, host/capture's write_file_atomic) so that a reader never sees half a mesh.
#pragma once

#include "common/status.hpp"
#include "recon/types.hpp"

#include <string>
#include <vector>

namespace facescan::mesh_io {

struct DracoOptions {
	int position_bits = 14; // quantisation of positions over the mesh's bounding box
	int uv_bits = 12;
	int normal_bits = 10;
	int colour_bits = 8;
	int speed = 5;		// Draco's encode/decode speed 0 (best compression) .. 10 (fastest)
	bool normals = true;	// store normals when the mesh has them
};

/// Largest position error the quantisation allows for a mesh with this bounding-box extent
/// (the longest side, in mm): extent / (2^bits - 1), i.e. one quantisation step.
double draco_position_step(double extent, int position_bits);

/// Encodes positions, triangles, and when present UVs, normals and per-vertex colours.
/// -EINVAL for an empty mesh, a triangle index out of range or attribute sizes that differ from
/// the vertex count; -EIO when Draco refuses.
Status encode_draco(const recon::Mesh &mesh, const DracoOptions &options, std::vector<char> *ret_bytes);
/// Decodes a Draco mesh (not a point cloud). Vertices may come back reordered and merged by the
/// codec; the texture image is not part of the Draco bytes.
Status decode_draco(const void *data, size_t size, recon::Mesh *ret_mesh);

/// Binary little-endian PLY: x y z [nx ny nz] [red green blue] [texture_u texture_v], faces as
/// `list uchar int vertex_indices`.
Status encode_ply(const recon::Mesh &mesh, std::string *ret_bytes);
/// Reads ASCII or binary little/big-endian PLY with float/double/int vertex properties and
/// triangle or polygon faces (polygons are fanned into triangles). Unknown elements and
/// properties are skipped.
Status decode_ply(const void *data, size_t size, recon::Mesh *ret_mesh);

/// File helpers. Writes are atomic; errors name the path.
Status write_draco(const std::string &path, const recon::Mesh &mesh, const DracoOptions &options);
Status read_draco(const std::string &path, recon::Mesh *ret_mesh);
Status write_ply(const std::string &path, const recon::Mesh &mesh);
Status read_ply(const std::string &path, recon::Mesh *ret_mesh);
/// Reads a whole file into memory (-ENOENT missing, -EIO unreadable).
Status read_file_bytes(const std::string &path, std::string *ret_bytes);

} // namespace facescan::mesh_io
