// facescan convert: mesh format conversion between .drc .ply .glb .obj .stl (by the extensions).
#include "facescan/outputs.hpp"
#include "mesh_io/mesh_io.hpp"

#include <getopt.h>
#include <sys/stat.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace facescan::cli {

static void convert_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan convert [--units mm|m] [--in-units mm|m] [--texture PNG] IN OUT\n"
		     "\n"
		     "Converts a mesh between .drc (Draco), .ply, .glb (glTF 2.0 binary, Draco-compressed,\n"
		     "texture embedded, metres), .obj (+ OUT-stem.mtl + OUT-stem_texture.png) and binary\n"
		     ".stl, chosen by the extensions. Positions, triangles, UVs, normals and colours are\n"
		     "kept where the output format has them (STL: triangles only; PLY: no texture image).\n"
		     "  --units mm|m   what 1.0 means in the OUT .ply/.obj/.stl (default mm)\n"
		     "  --in-units mm|m  the same for the IN .ply/.obj/.stl (default mm)\n"
		     "                 (.drc is mm, as facescan writes it; .glb is metres, as glTF says)\n"
		     "  --texture PNG  the texture of a .drc/.ply input (default: IN-stem.png when it exists)\n"
		     "Every output file is written atomically; the input is never changed.\n");
}

static bool exists(const std::string &p)
{
	struct stat st;
	return stat(p.c_str(), &st) == 0;
}

static std::string strip_ext(const std::string &p)
{
	const size_t dot = p.rfind('.'), slash = p.rfind('/');
	return dot == std::string::npos || (slash != std::string::npos && dot < slash) ? p : p.substr(0, dot);
}

int convert_main(int argc, char **argv)
{
	static const option options[] = {{"help", no_argument, nullptr, 'h'},
					 {"units", required_argument, nullptr, 'u'},
					 {"texture", required_argument, nullptr, 't'},
					 {"in-units", required_argument, nullptr, 'i'},
					 {nullptr, 0, nullptr, 0}};
	mesh_io::Units units = mesh_io::Units::mm, in_units = mesh_io::Units::mm;
	std::string texture;
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "h", options, nullptr)) != -1;) {
		if (opt == 'h') {
			convert_usage(stdout);
			return 0;
		}
		if (opt == 'u' || opt == 'i') {
			Status s = mesh_io::parse_units(optarg, opt == 'u' ? &units : &in_units);
			if (!s.ok()) {
				std::fprintf(stderr, "facescan convert: --%s\n", s.message().c_str());
				return 2;
			}
			continue;
		}
		if (opt == 't') {
			texture = optarg;
			continue;
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
	mesh_io::Format fin, fout;
	for (auto [p, f] : {std::pair{&in, &fin}, std::pair{&out, &fout}}) {
		Status s = mesh_io::format_of(*p, f);
		if (!s.ok()) {
			std::fprintf(stderr, "facescan convert: %s\n", s.message().c_str());
			return 2;
		}
	}
	// Every file the output consists of: none may be the input, its texture or another output.
	const std::string out_ext = out.substr(strip_ext(out).size());
	std::vector<std::pair<std::string, const char *>> outs = {{out, out_ext.c_str()}};
	if (fout == mesh_io::Format::obj)
		outs = {{out, out_ext.c_str()}, {strip_ext(out) + ".mtl", ".mtl"}, {strip_ext(out) + "_texture.png", ".png"}};
	if (texture.empty() && (fin == mesh_io::Format::drc || fin == mesh_io::Format::ply) &&
	    exists(strip_ext(in) + ".png"))
		texture = strip_ext(in) + ".png";
	std::vector<InputFile> inputs = {{in, "the input mesh"}};
	if (!texture.empty())
		inputs.push_back({texture, "the input's texture"});
	std::string why;
	if (!check_outputs(inputs, outs, &why)) {
		std::fprintf(stderr, "facescan convert: %s\n", why.c_str());
		return 2;
	}

	recon::Mesh mesh;
	const auto t0 = std::chrono::steady_clock::now();
	Status s = mesh_io::read_mesh(in, in_units, texture, &mesh);
	const auto t1 = std::chrono::steady_clock::now();
	if (s.ok())
		s = mesh_io::write_mesh(out, mesh, units, mesh_io::DracoOptions());
	const auto t2 = std::chrono::steady_clock::now();
	if (!s.ok()) {
		std::fprintf(stderr, "facescan convert: %s\n", s.message().c_str());
		return 1;
	}
	auto ms = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
	std::printf("facescan convert: %s -> %s: %zu vertices, %zu triangles%s (read %.0f ms, write %.0f ms)\n",
		    in.c_str(), out.c_str(), mesh.positions.size(), mesh.triangles.size(),
		    mesh.texture.empty() ? "" : ", textured", ms(t0, t1), ms(t1, t2));
	return 0;
}

} // namespace facescan::cli
