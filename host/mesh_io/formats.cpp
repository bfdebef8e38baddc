// One entry for every mesh format: chosen by the file's extension.
#include "mesh_io/mesh_io.hpp"

#include <opencv2/imgcodecs.hpp>

namespace facescan::mesh_io {

namespace {

bool ends_with(const std::string &s, const char *suffix)
{
	const std::string e(suffix);
	return s.size() > e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

void scale_positions(recon::Mesh *mesh, float k)
{
	for (cv::Point3f &p : mesh->positions)
		p *= k;
}

} // namespace

Status parse_units(const std::string &text, Units *ret_units)
{
	if (text == "mm")
		*ret_units = Units::mm;
	else if (text == "m")
		*ret_units = Units::m;
	else
		return Status::error(-EINVAL, "units: '" + text + "' is not mm or m");
	return {};
}

Status format_of(const std::string &path, Format *ret_format)
{
	static const std::pair<const char *, Format> table[] = {{".drc", Format::drc}, {".ply", Format::ply},
								 {".glb", Format::glb}, {".obj", Format::obj},
								 {".stl", Format::stl}};
	for (const auto &[ext, f] : table)
		if (ends_with(path, ext)) {
			*ret_format = f;
			return {};
		}
	return Status::error(-EINVAL, path + ": extension must be .drc, .ply, .glb, .obj or .stl");
}

Status read_mesh(const std::string &path, Units units, const std::string &texture_png, recon::Mesh *ret_mesh)
{
	Format f;
	Status s = format_of(path, &f);
	if (!s.ok())
		return s;
	recon::Mesh mesh;
	// OBJ, STL and the texture are opened by assimp and imread, which would wait on a FIFO.
	s = check_regular_input(path);
	if (s.ok() && !texture_png.empty() && (f == Format::drc || f == Format::ply))
		s = check_regular_input(texture_png);
	if (!s.ok())
		return s;
	switch (f) {
	case Format::drc: s = read_draco(path, &mesh); break;
	case Format::ply:
		s = read_ply(path, &mesh);
		if (s.ok() && units == Units::m)
			scale_positions(&mesh, 1000.0f);
		break;
	case Format::glb: s = read_glb(path, &mesh); break;
	case Format::obj: s = read_obj(path, units, &mesh); break;
	case Format::stl: s = read_stl(path, units, &mesh); break;
	}
	if (!s.ok())
		return s;
	if (!texture_png.empty() && (f == Format::drc || f == Format::ply)) {
		mesh.texture = cv::imread(texture_png, cv::IMREAD_COLOR);
		if (mesh.texture.empty())
			return Status::error(-ENOENT, texture_png + ": texture missing or not an image");
	}
	*ret_mesh = std::move(mesh);
	return {};
}

Status write_mesh(const std::string &path, const recon::Mesh &mesh, Units units, const DracoOptions &options)
{
	Format f;
	Status s = format_of(path, &f);
	if (!s.ok())
		return s;
	switch (f) {
	case Format::drc: return write_draco(path, mesh, options);
	case Format::ply:
		if (units == Units::m) {
			recon::Mesh m = mesh;
			scale_positions(&m, 0.001f);
			return write_ply(path, m);
		}
		return write_ply(path, mesh);
	case Format::glb: return write_glb(path, mesh, options);
	case Format::obj: {
		const size_t slash = path.rfind('/');
		const std::string name = path.substr(slash == std::string::npos ? 0 : slash + 1);
		return write_obj(path, mesh, units, name.substr(0, name.size() - 4) + "_texture.png", true, nullptr);
	}
	case Format::stl: return write_stl(path, mesh, units);
	}
	return Status::error(-EINVAL, path + ": unknown format");
}

} // namespace facescan::mesh_io
