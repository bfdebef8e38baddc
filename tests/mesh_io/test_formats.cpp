// Round trips of the clinic formats (.glb, .obj + .mtl + texture, binary .stl, and the
// extension dispatch): write → read → compare positions within Draco's quantisation (or the
// text format's printed precision), UVs, the texture pixel for pixel, and the triangle count.
// Bad input is refused with the file named and nothing written.
#include "mesh_io/mesh_io.hpp"
#include "mesh_compare.hpp"

#include <opencv2/imgproc.hpp>

#include <dirent.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>

extern "C" {
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
}

using facescan::recon::Mesh;
namespace mio = facescan::mesh_io;
using facescan::testing::face_set;
using facescan::testing::match_vertices;

static std::string g_dir;

// A bumpy 30x20 sheet, 58 x 38 mm at z ~ 500 mm, UVs (v down, as recon), normals, a texture.
static Mesh make_face_like()
{
	Mesh m;
	const int nx = 30, ny = 20;
	for (int j = 0; j < ny; ++j)
		for (int i = 0; i < nx; ++i) {
			const float x = float(i) * 2.0f - 29.0f, y = float(j) * 2.0f - 19.0f;
			m.positions.emplace_back(x, y, 500.0f + 5.0f * std::sin(x * 0.1f) * std::cos(y * 0.1f));
			m.uvs.emplace_back(float(i) / float(nx - 1), float(j) / float(ny - 1));
			m.normals.emplace_back(0.0f, 0.0f, 1.0f);
		}
	for (int j = 0; j + 1 < ny; ++j)
		for (int i = 0; i + 1 < nx; ++i) {
			const int a = j * nx + i;
			m.triangles.emplace_back(a, a + 1, a + nx + 1);
			m.triangles.emplace_back(a, a + nx + 1, a + nx);
		}
	m.texture = cv::Mat(48, 64, CV_8UC3);
	for (int y = 0; y < 48; ++y)
		for (int x = 0; x < 64; ++x)
			m.texture.at<cv::Vec3b>(y, x) = cv::Vec3b(uint8_t(x * 4), uint8_t(y * 5), uint8_t((x ^ y) * 3));
	return m;
}

// Same vertices (within tol), same triangles with the same winding, UVs within uv_tol.
static void assert_same_mesh(const char *what, const Mesh &orig, const Mesh &got, double tol, double uv_tol)
{
	double worst = 0;
	const std::vector<int> map = match_vertices(orig, got, tol, &worst);
	std::printf("%s: %zu vertices, %zu triangles, worst position error %.6f mm (tolerance %.6f)\n", what,
		    got.positions.size(), got.triangles.size(), worst, tol);
	assert_int_equal(got.positions.size(), orig.positions.size());
	assert_int_equal(got.triangles.size(), orig.triangles.size());
	for (int v : map)
		assert_true(v >= 0);
	assert_true(face_set(got.triangles, &map) == face_set(orig.triangles, nullptr));
	if (uv_tol >= 0) {
		assert_int_equal(got.uvs.size(), got.positions.size());
		double uv_worst = 0;
		for (size_t i = 0; i < map.size(); ++i) {
			const cv::Point2f d = got.uvs[i] - orig.uvs[size_t(map[i])];
			uv_worst = std::max(uv_worst, double(std::max(std::fabs(d.x), std::fabs(d.y))));
		}
		std::printf("%s: worst UV error %.6f (tolerance %.6f)\n", what, uv_worst, uv_tol);
		assert_true(uv_worst <= uv_tol);
	}
}

static void assert_same_image(const cv::Mat &a, const cv::Mat &b)
{
	assert_false(b.empty());
	assert_int_equal(a.rows, b.rows);
	assert_int_equal(a.cols, b.cols);
	assert_int_equal(a.type(), b.type());
	assert_int_equal(cv::norm(a, b, cv::NORM_INF), 0);
}

static size_t files_in(const std::string &dir)
{
	size_t n = 0;
	DIR *d = opendir(dir.c_str());
	if (!d)
		return 0;
	while (dirent *e = readdir(d))
		n += e->d_name[0] != '.';
	closedir(d);
	return n;
}

static void test_glb_round_trip(void **)
{
	const Mesh m = make_face_like();
	mio::DracoOptions opt;
	std::string bytes;
	assert_true(mio::encode_glb(m, opt, &bytes).ok());
	assert_true(bytes.size() > 12 && bytes.compare(0, 4, "glTF") == 0);
	assert_true(bytes.find("KHR_draco_mesh_compression") != std::string::npos);
	Mesh d;
	facescan::Status s = mio::decode_glb(bytes.data(), bytes.size(), &d);
	if (!s.ok())
		std::printf("decode_glb: %s\n", s.message().c_str());
	assert_true(s.ok());
	// Quantisation over the longest side (58 mm) plus float rounding of mm → m → mm.
	const double step = mio::draco_position_step(58.0, opt.position_bits) + 1e-4;
	assert_same_mesh("glb", m, d, step, 1.0 / ((1 << opt.uv_bits) - 1));
	assert_same_image(m.texture, d.texture);
	std::printf("glb: %zu bytes\n", bytes.size());
}

static void test_glb_refuses_bad_input(void **)
{
	Mesh d;
	const std::string junk = "glTF this is not a glb at all";
	assert_int_equal(mio::decode_glb(junk.data(), junk.size(), &d).code(), -EINVAL);
	std::string bytes;
	assert_true(mio::encode_glb(make_face_like(), {}, &bytes).ok());
	const std::string cut = bytes.substr(0, bytes.size() / 2);
	assert_int_equal(mio::decode_glb(cut.data(), cut.size(), &d).code(), -EINVAL);
	Mesh bad = make_face_like();
	bad.triangles.emplace_back(0, 1, 100000);
	assert_int_equal(mio::encode_glb(bad, {}, &bytes).code(), -EINVAL);
	const facescan::Status s = mio::read_glb(g_dir + "/missing.glb", &d);
	assert_int_equal(s.code(), -ENOENT);
	assert_true(s.message().find("missing.glb") != std::string::npos);
}

static void test_obj_round_trip(void **)
{
	const Mesh m = make_face_like();
	const std::string dir = g_dir + "/obj";
	assert_int_equal(mkdir(dir.c_str(), 0755), 0);
	mio::ObjFiles files;
	facescan::Status s = mio::write_obj(dir + "/scan.obj", m, mio::Units::mm, "scan_texture.png", true, &files);
	if (!s.ok())
		std::printf("write_obj: %s\n", s.message().c_str());
	assert_true(s.ok());
	assert_string_equal(files.mtl.c_str(), (dir + "/scan.mtl").c_str());
	assert_string_equal(files.texture.c_str(), (dir + "/scan_texture.png").c_str());
	assert_int_equal(files_in(dir), 3); // obj, mtl, png: no temp file left
	std::ifstream mtl(files.mtl);
	const std::string text((std::istreambuf_iterator<char>(mtl)), std::istreambuf_iterator<char>());
	assert_true(text.find("map_Kd scan_texture.png") != std::string::npos);
	Mesh d;
	s = mio::read_obj(dir + "/scan.obj", mio::Units::mm, &d);
	if (!s.ok())
		std::printf("read_obj: %s\n", s.message().c_str());
	assert_true(s.ok());
	// OBJ is text: positions as printed (>= 6 significant digits of ~500 mm).
	assert_same_mesh("obj", m, d, 1e-3, 1e-5);
	assert_same_image(m.texture, d.texture);

	// In metres the numbers are 1000x smaller and come back as mm.
	assert_true(mio::write_obj(dir + "/m.obj", m, mio::Units::m, "scan_texture.png", false, nullptr).ok());
	assert_true(mio::read_obj(dir + "/m.obj", mio::Units::m, &d).ok());
	assert_same_mesh("obj (m)", m, d, 1e-3, 1e-5);
	assert_true(mio::read_obj(dir + "/m.obj", mio::Units::mm, &d).ok());
	assert_true(std::fabs(d.positions[0].z - 0.5f) < 0.01f); // read as mm: 0.5 "mm"
}

static void test_obj_refuses_bad_input(void **)
{
	const std::string dir = g_dir + "/objbad";
	assert_int_equal(mkdir(dir.c_str(), 0755), 0);
	Mesh d;
	{
		std::ofstream f(dir + "/notex.obj");
		f << "mtllib notex.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3\n";
		std::ofstream g(dir + "/notex.mtl");
		g << "newmtl a\nmap_Kd gone.png\n";
	}
	facescan::Status s = mio::read_obj(dir + "/notex.obj", mio::Units::mm, &d);
	assert_false(s.ok());
	assert_true(s.message().find("gone.png") != std::string::npos);
	{
		std::ofstream f(dir + "/junk.obj");
		f << "this is not an obj\n";
	}
	assert_false(mio::read_obj(dir + "/junk.obj", mio::Units::mm, &d).ok());
	const size_t before = files_in(dir);
	assert_false(mio::write_obj(dir + "/no/such/dir/x.obj", make_face_like(), mio::Units::mm, "x.png", true,
				    nullptr).ok());
	assert_int_equal(mio::write_obj(dir + "/y.obj", make_face_like(), mio::Units::mm, "../y.png", true,
					nullptr).code(), -EINVAL);
	assert_int_equal(files_in(dir), before);
}

static void test_stl_round_trip(void **)
{
	Mesh m = make_face_like();
	const std::string path = g_dir + "/scan.stl";
	assert_true(mio::write_stl(path, m, mio::Units::mm).ok());
	struct stat st;
	assert_int_equal(stat(path.c_str(), &st), 0);
	// Binary STL: 80-byte header, count, 50 bytes per triangle.
	assert_int_equal(st.st_size, 84 + 50 * m.triangles.size());
	Mesh d;
	facescan::Status s = mio::read_stl(path, mio::Units::mm, &d);
	if (!s.ok())
		std::printf("read_stl: %s\n", s.message().c_str());
	assert_true(s.ok());
	assert_true(d.uvs.empty());
	assert_same_mesh("stl", m, d, 1e-5, -1); // float32, exact
	assert_true(mio::write_stl(path, m, mio::Units::m).ok());
	assert_true(mio::read_stl(path, mio::Units::m, &d).ok());
	assert_same_mesh("stl (m)", m, d, 1e-3, -1);
	assert_false(mio::read_stl(g_dir + "/none.stl", mio::Units::mm, &d).ok());
}

static void test_dispatch_by_extension(void **)
{
	const Mesh m = make_face_like();
	mio::Format f;
	assert_int_equal(mio::format_of("a.xyz", &f).code(), -EINVAL);
	assert_int_equal(mio::format_of(".glb", &f).code(), -EINVAL);
	assert_true(mio::format_of("dir/a.glb", &f).ok() && f == mio::Format::glb);
	mio::Units u;
	assert_int_equal(mio::parse_units("cm", &u).code(), -EINVAL);
	assert_true(mio::parse_units("m", &u).ok() && u == mio::Units::m);
	for (const char *ext : {".drc", ".ply", ".glb", ".obj", ".stl"}) {
		const std::string p = g_dir + "/any" + ext;
		assert_true(mio::write_mesh(p, m, mio::Units::mm, {}).ok());
		Mesh d;
		facescan::Status s = mio::read_mesh(p, mio::Units::mm, "", &d);
		if (!s.ok())
			std::printf("%s: %s\n", ext, s.message().c_str());
		assert_true(s.ok());
		assert_int_equal(d.triangles.size(), m.triangles.size());
		const bool textured = std::string(ext) == ".glb" || std::string(ext) == ".obj";
		assert_int_equal(!d.texture.empty(), textured);
	}
}

static int make_dir(void **)
{
	char tmpl[] = "/tmp/facescan-formats.XXXXXX";
	if (!mkdtemp(tmpl))
		return -1;
	g_dir = tmpl;
	return 0;
}

static int remove_dir(void **)
{
	const std::string cmd = "rm -rf '" + g_dir + "'";
	return std::system(cmd.c_str()) == 0 ? 0 : -1;
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_glb_round_trip),	     cmocka_unit_test(test_glb_refuses_bad_input),
		cmocka_unit_test(test_obj_round_trip),	     cmocka_unit_test(test_obj_refuses_bad_input),
		cmocka_unit_test(test_stl_round_trip),	     cmocka_unit_test(test_dispatch_by_extension),
	};
	return cmocka_run_group_tests(tests, make_dir, remove_dir);
}
