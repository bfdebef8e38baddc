// File helpers and the shared consistency check of host/mesh_io.
#include "mesh_io/mesh_io.hpp"
#include "mesh_io/mesh_check.hpp"

#include "capture/capture_set.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace facescan::mesh_io {

Status read_file_bytes(const std::string &path, std::string *ret_bytes)
{
	return read_regular_file(path, kMaxInputFileBytes, ret_bytes);
}

Status check_regular_input(const std::string &path)
{
	return check_regular_file(path, kMaxInputFileBytes);
}

Status write_draco(const std::string &path, const recon::Mesh &mesh, const DracoOptions &options)
{
	std::vector<char> bytes;
	Status s = encode_draco(mesh, options, &bytes);
	if (!s.ok())
		return Status::error(s.code(), path + ": " + s.message());
	return write_file_atomic(path, bytes.data(), bytes.size());
}

Status read_draco(const std::string &path, recon::Mesh *ret_mesh)
{
	std::string bytes;
	Status s = read_file_bytes(path, &bytes);
	if (!s.ok())
		return s;
	s = decode_draco(bytes.data(), bytes.size(), ret_mesh);
	if (!s.ok())
		return Status::error(s.code(), path + ": " + s.message());
	return {};
}

Status write_ply(const std::string &path, const recon::Mesh &mesh)
{
	std::string bytes;
	Status s = encode_ply(mesh, &bytes);
	if (!s.ok())
		return Status::error(s.code(), path + ": " + s.message());
	return write_file_atomic(path, bytes.data(), bytes.size());
}

Status read_ply(const std::string &path, recon::Mesh *ret_mesh)
{
	std::string bytes;
	Status s = read_file_bytes(path, &bytes);
	if (!s.ok())
		return s;
	s = decode_ply(bytes.data(), bytes.size(), ret_mesh);
	if (!s.ok())
		return Status::error(s.code(), path + ": " + s.message());
	return {};
}

} // namespace facescan::mesh_io
