// Mesh files: Draco (the product's output), PLY (inspection, ground truth), and the formats a
// clinic opens: glTF binary (.glb, Draco-compressed, texture embedded), OBJ (+ .mtl + texture
// .png) and binary STL. Encoders and decoders work on bytes in memory where the format is one
// file; the write_* helpers add the atomic file write (temp file + rename, host/capture's
// write_file_atomic) so that a reader never sees half a mesh.
// Libraries do the formats: Draco, tinygltf (glb container), assimp (OBJ, STL); PLY predates them.
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
	// Draco's encode/decode speed 0 (best compression) .. 10 (fastest). 6 rather than 5: the
	// same decoded vertices (positions, UVs, normals) and a file 0.1 % smaller on the bench's
	// dense face meshes, encoded in 0.08 instead of 0.14 CPU s and decoded in 0.05 instead of 0.08.
	int speed = 6;
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
/// The largest file a mesh reader takes (a 5M-vertex binary PLY is ~150 MB).
constexpr size_t kMaxInputFileBytes = size_t(1) << 30;
/// Reads a whole regular file of at most kMaxInputFileBytes into memory (read_regular_file:
/// a FIFO or device is refused, never waited on): -ENOENT missing, -EINVAL not a regular file,
/// -EFBIG too large, -errno.
Status read_file_bytes(const std::string &path, std::string *ret_bytes);
/// The same checks without reading, for the readers that open the file themselves (assimp,
/// OpenCV's imread).
Status check_regular_input(const std::string &path);

/// glTF 2.0 binary: one mesh, one primitive compressed with KHR_draco_mesh_compression
/// (required extension), positions in metres (glTF's unit; recon::Mesh is mm, so ×0.001 on
/// write, ×1000 on read), the texture embedded as PNG in a PBR material (metallic 0, rough 1),
/// else vertex colours. World frame = glTF's: +y up, +z out of the face.
/// -EINVAL bad mesh / not a glb / no Draco primitive, -EIO when an encoder refuses.
Status encode_glb(const recon::Mesh &mesh, const DracoOptions &options, std::string *ret_bytes);
Status decode_glb(const void *data, size_t size, recon::Mesh *ret_mesh);
Status write_glb(const std::string &path, const recon::Mesh &mesh, const DracoOptions &options);
Status read_glb(const std::string &path, recon::Mesh *ret_mesh);

/// Length unit of a file whose format has none (PLY, OBJ, STL): what 1.0 in the file means.
enum class Units { mm, m };
/// "mm" / "m" → Units; -EINVAL otherwise.
Status parse_units(const std::string &text, Units *ret_units);

/// Binary STL (assimp's exporter): triangles only, positions in `units`.
Status encode_stl(const recon::Mesh &mesh, Units units, std::string *ret_bytes);
Status write_stl(const std::string &path, const recon::Mesh &mesh, Units units);
/// Reads binary or ASCII STL; vertices shared by triangles are merged.
Status read_stl(const std::string &path, Units units, recon::Mesh *ret_mesh);

/// OBJ (assimp's exporter) with its material file <stem>.mtl beside it; when the mesh has a
/// texture the MTL names `texture_name` (a file name beside the OBJ), written as PNG unless
/// `write_texture` is false (the caller already has it there, as facescand's <base>.png).
/// Positions in `units`; texture v runs up as OBJ readers expect (recon's v runs down).
struct ObjFiles {
	std::string obj, mtl, texture; // paths written (texture empty when none)
};
Status write_obj(const std::string &path, const recon::Mesh &mesh, Units units,
		 const std::string &texture_name, bool write_texture, ObjFiles *ret_files);
/// Reads an OBJ, its MTL and the first diffuse texture it names (when present).
Status read_obj(const std::string &path, Units units, recon::Mesh *ret_mesh);

/// The formats by extension: .drc .ply .glb .obj .stl (lowercase).
enum class Format { drc, ply, glb, obj, stl };
/// -EINVAL (naming the extension) for anything else.
Status format_of(const std::string &path, Format *ret_format);
/// Reads any of the formats. .drc / .ply take their texture from `texture_png` when it is not
/// empty (the daemon writes <base>.png beside <base>.drc). `units` applies to .ply/.obj/.stl.
Status read_mesh(const std::string &path, Units units, const std::string &texture_png, recon::Mesh *ret_mesh);
/// Writes any of the formats; an .obj's texture goes to <stem>_texture.png beside it.
Status write_mesh(const std::string &path, const recon::Mesh &mesh, Units units, const DracoOptions &options);

} // namespace facescan::mesh_io
