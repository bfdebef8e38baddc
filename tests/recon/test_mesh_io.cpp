// Draco and PLY round trips: encode → decode → compare within the quantisation.
#include "mesh_io/mesh_io.hpp"
#include "mesh_compare.hpp"

#include <cmath>
#include <cstdio>
#include <map>
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

// A bumpy 30x20 grid sheet, 60 x 40 mm, with UVs, normals and colours.
static Mesh make_sheet()
{
	Mesh m;
	const int nx = 30, ny = 20;
	for (int j = 0; j < ny; ++j)
		for (int i = 0; i < nx; ++i) {
			const float x = float(i) * 2.0f, y = float(j) * 2.0f;
			m.positions.emplace_back(x, y, 500.0f + 5.0f * std::sin(x * 0.1f) * std::cos(y * 0.1f));
			m.uvs.emplace_back(float(i) / float(nx - 1), float(j) / float(ny - 1));
			m.normals.emplace_back(0.0f, 0.0f, 1.0f);
			m.colours.emplace_back(uint8_t(i * 8), uint8_t(j * 12), 77);
		}
	for (int j = 0; j + 1 < ny; ++j)
		for (int i = 0; i + 1 < nx; ++i) {
			const int a = j * nx + i;
			m.triangles.emplace_back(a, a + 1, a + nx + 1);
			m.triangles.emplace_back(a, a + nx + 1, a + nx);
		}
	return m;
}

static void test_draco_round_trip(void **)
{
	const Mesh m = make_sheet();
	mio::DracoOptions opt;
	std::vector<char> bytes;
	facescan::Status s = mio::encode_draco(m, opt, &bytes);
	assert_true(s.ok());
	Mesh d;
	s = mio::decode_draco(bytes.data(), bytes.size(), &d);
	assert_true(s.ok());
	assert_int_equal(d.positions.size(), m.positions.size());
	assert_int_equal(d.triangles.size(), m.triangles.size());
	assert_int_equal(d.uvs.size(), d.positions.size());
	assert_int_equal(d.colours.size(), d.positions.size());
	const double step = mio::draco_position_step(58.0, opt.position_bits);
	std::printf("draco: %zu bytes, position step %.5f mm\n", bytes.size(), step);
	const std::vector<int> map = match_vertices(m, d, step);
	for (int v : map)
		assert_true(v >= 0);
	assert_true(face_set(d.triangles, &map) == face_set(m.triangles, nullptr));
	const double uv_step = 1.0 / ((1 << opt.uv_bits) - 1);
	for (size_t i = 0; i < map.size(); ++i) {
		const cv::Point2f du = d.uvs[i] - m.uvs[size_t(map[i])];
		assert_true(std::fabs(du.x) <= uv_step && std::fabs(du.y) <= uv_step);
		assert_true(d.colours[i] == m.colours[size_t(map[i])]);
		assert_true(std::fabs(d.normals[i].z - 1.0f) < 0.01f);
	}
}

static void test_draco_refuses_bad_input(void **)
{
	Mesh m = make_sheet();
	m.triangles.emplace_back(0, 1, int(m.positions.size()));
	std::vector<char> bytes;
	assert_int_equal(mio::encode_draco(m, {}, &bytes).code(), -EINVAL);
	Mesh empty;
	assert_int_equal(mio::encode_draco(empty, {}, &bytes).code(), -EINVAL);
	const char junk[] = "this is not draco";
	Mesh d;
	assert_false(mio::decode_draco(junk, sizeof junk, &d).ok());
}

static void test_ply_round_trip(void **)
{
	const Mesh m = make_sheet();
	std::string bytes;
	assert_true(mio::encode_ply(m, &bytes).ok());
	Mesh d;
	assert_true(mio::decode_ply(bytes.data(), bytes.size(), &d).ok());
	assert_int_equal(d.positions.size(), m.positions.size());
	for (size_t i = 0; i < m.positions.size(); ++i) {
		assert_true(d.positions[i] == m.positions[i]);
		assert_true(d.uvs[i] == m.uvs[i]);
		assert_true(d.colours[i] == m.colours[i]);
	}
	assert_true(d.triangles == m.triangles);
}

static void test_ply_ascii_quads(void **)
{
	const std::string ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\n"
				"property double y\nproperty double z\nelement face 1\n"
				"property list uchar uint vertex_index\nend_header\n"
				"0 0 0\n1 0 0\n1 1 0\n0 1 0.5\n4 0 1 2 3\n";
	Mesh d;
	assert_true(mio::decode_ply(ply.data(), ply.size(), &d).ok());
	assert_int_equal(d.positions.size(), 4);
	assert_int_equal(d.triangles.size(), 2);
	assert_true(std::fabs(d.positions[3].z - 0.5f) < 1e-6f);
	const std::string truncated = ply.substr(0, ply.size() - 6);
	assert_false(mio::decode_ply(truncated.data(), truncated.size(), &d).ok());
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_draco_round_trip),
		cmocka_unit_test(test_draco_refuses_bad_input),
		cmocka_unit_test(test_ply_round_trip),
		cmocka_unit_test(test_ply_ascii_quads),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
