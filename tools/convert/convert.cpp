// facescan convert: mesh format conversion, Draco ↔ PLY (by the file extensions).
#include "mesh_io/mesh_io.hpp"

#include <getopt.h>

#include <cstdio>
#include <string>

namespace facescan::cli {

static void convert_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan convert IN.{drc,ply} OUT.{drc,ply}\n"
		     "\n"
		     "Converts a mesh between Draco and PLY, keeping positions, triangles, UVs, normals\n"
		     "and per-vertex colours (Draco quantises positions to 14 bits over the bounding box).\n"
		     "The output is written atomically.\n");
}

static bool has_ext(const std::string &p, const char *ext)
{
	const std::string e(ext);
	return p.size() > e.size() && p.compare(p.size() - e.size(), e.size(), e) == 0;
}

int convert_main(int argc, char **argv)
{
	static const option options[] = {{"help", no_argument, nullptr, 'h'}, {nullptr, 0, nullptr, 0}};
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "h", options, nullptr)) != -1;) {
		if (opt == 'h') {
			convert_usage(stdout);
			return 0;
		}
		convert_usage(stderr);
		return 2;
	}
	if (optind + 2 != argc) {
		std::fprintf(stderr, "facescan convert: need IN and OUT\n");
		convert_usage(stderr);
		return 2;
	}
	const std::string in = argv[optind], out = argv[optind + 1];
	for (const std::string &p : {in, out})
		if (!has_ext(p, ".drc") && !has_ext(p, ".ply")) {
			std::fprintf(stderr, "facescan convert: '%s': extension must be .drc or .ply\n", p.c_str());
			return 2;
		}
	recon::Mesh mesh;
	Status s = has_ext(in, ".drc") ? mesh_io::read_draco(in, &mesh) : mesh_io::read_ply(in, &mesh);
	if (s.ok())
		s = has_ext(out, ".drc") ? mesh_io::write_draco(out, mesh, mesh_io::DracoOptions())
					 : mesh_io::write_ply(out, mesh);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan convert: %s\n", s.message().c_str());
		return 1;
	}
	std::printf("facescan convert: %s -> %s: %zu vertices, %zu triangles\n", in.c_str(), out.c_str(),
		    mesh.positions.size(), mesh.triangles.size());
	return 0;
}

} // namespace facescan::cli
