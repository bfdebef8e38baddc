// host/eval: point-triangle distance, and metrics of a known offset surface.
#include "eval/eval.hpp"
#include "mesh_io/mesh_io.hpp"
#include "recon/dense.hpp"
#include "recon/fusion.hpp"

#include "cmocka.hpp"
#include "synthetic_rig.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

#include <sys/stat.h>
#include <unistd.h>

using namespace facescan;

static void test_point_triangle_distance(void **)
{
	const cv::Point3d a(0, 0, 0), b(10, 0, 0), c(0, 10, 0);
	assert_true(std::fabs(eval::point_triangle_distance({2, 2, 3}, a, b, c) - 3) < 1e-12);     // face
	assert_true(std::fabs(eval::point_triangle_distance({-3, -4, 0}, a, b, c) - 5) < 1e-12);   // vertex a
	assert_true(std::fabs(eval::point_triangle_distance({5, -2, 0}, a, b, c) - 2) < 1e-12);    // edge ab
	assert_true(std::fabs(eval::point_triangle_distance({6, 6, 0}, a, b, c) - std::sqrt(2.0)) < 1e-12); // edge bc
}

// A UV-sphere patch facing +z of radius r.
static recon::Mesh sphere(double r)
{
	recon::Mesh m;
	const int nu = 120, nv = 80;
	for (int j = 0; j <= nv; ++j)
		for (int i = 0; i <= nu; ++i) {
			const double el = (-60 + 120.0 * j / nv) * CV_PI / 180, az = (-80 + 160.0 * i / nu) * CV_PI / 180;
			m.positions.emplace_back(float(r * std::cos(el) * std::sin(az)), float(r * std::sin(el)),
						 float(r * std::cos(el) * std::cos(az) - 60));
		}
	for (int j = 0; j < nv; ++j)
		for (int i = 0; i < nu; ++i) {
			const int a = j * (nu + 1) + i;
			m.triangles.emplace_back(a, a + 1, a + nu + 2);
			m.triangles.emplace_back(a, a + nu + 2, a + nu + 1);
		}
	return m;
}

static void test_offset_surface(void **)
{
	const recon::Mesh truth = sphere(85), recon = sphere(85.2);
	eval::EvalResult r;
	assert_true(eval::evaluate(recon, truth, synth::ring(), {}, eval::EvalParams(), &r).ok());
	std::printf("offset 0.2 mm: RMS %.4f median %.4f p95 %.4f, completeness %.3f of %d\n", r.rms_mm, r.median_mm,
		    r.p95_mm, r.completeness, r.truth_counted);
	assert_true(std::fabs(r.rms_mm - 0.2) < 0.01);
	assert_true(std::fabs(r.median_mm - 0.2) < 0.01);
	assert_true(r.truth_counted > r.truth_points / 2 && r.truth_counted < r.truth_points);
	assert_true(r.completeness > 0.99);
	eval::EvalParams tight;
	tight.completeness_mm = 0.1;
	assert_true(eval::evaluate(recon, truth, synth::ring(), {}, tight, &r).ok());
	assert_true(r.completeness < 0.01);
	// Half the reconstruction missing: completeness drops to about the half the cameras see.
	recon::Mesh half = recon;
	half.triangles.resize(half.triangles.size() / 2);
	assert_true(eval::evaluate(half, truth, synth::ring(), {}, eval::EvalParams(), &r).ok());
	std::printf("half: completeness %.3f\n", r.completeness);
	assert_true(r.completeness > 0.3 && r.completeness < 0.7);
	// The per-point verdict (facescan evaluate --coverage) adds up to the figures, and the
	// missed points are those far from the half that is left.
	assert_int_equal(r.truth_status.size(), truth.positions.size());
	int counted = 0, covered = 0;
	for (size_t i = 0; i < r.truth_status.size(); ++i) {
		counted += r.truth_status[i] >= 0;
		covered += r.truth_status[i] == 1;
	}
	assert_int_equal(counted, r.truth_counted);
	assert_true(std::abs(double(covered) / counted - r.completeness) < 1e-12);
	eval::MeshDistance to_half(half.positions, half.triangles, 2.0);
	for (size_t i = 0; i < r.truth_status.size(); ++i)
		if (r.truth_status[i] == 0)
			assert_true(to_half.distance(cv::Point3d(truth.positions[i]), 1.0) > 1.0);
	assert_int_equal(eval::evaluate(recon::Mesh(), truth, synth::ring(), {}, {}, &r).code(), -EINVAL);
}

// A vertex duplicated (a texture chart seam: same position, another UV) counts once: 100 copies of
// one vertex 5 mm off change nothing against one copy of it.
static void test_duplicates_count_once(void **)
{
	const recon::Mesh truth = sphere(85);
	recon::Mesh recon = sphere(85.2);
	recon.positions[0] = recon.positions[0] * float(90.2 / 85.2); // 5 mm off
	eval::EvalResult once, many;
	assert_true(eval::evaluate(recon, truth, synth::ring(), {}, eval::EvalParams(), &once).ok());
	recon::Mesh dup = recon;
	for (int k = 0; k < 100; ++k) {
		dup.positions.push_back(recon.positions[0]);
		dup.triangles.emplace_back(int(dup.positions.size()) - 1, 1, 2);
	}
	assert_true(eval::evaluate(dup, truth, synth::ring(), {}, eval::EvalParams(), &many).ok());
	std::printf("one copy: RMS %.5f over %d; 101 copies: RMS %.5f over %d\n", once.rms_mm, once.unique_positions,
		    many.rms_mm, many.unique_positions);
	assert_int_equal(once.unique_positions, int(recon.positions.size()));
	assert_int_equal(many.unique_positions, once.unique_positions);
	assert_true(std::fabs(many.rms_mm - once.rms_mm) < 1e-12);
	assert_true(once.max_mm > 4.9 && once.rms_mm < 0.25);
	// Per vertex (facescan evaluate --errors): every copy carries the distance.
	assert_int_equal(many.vertex_mm.size(), dup.positions.size());
	assert_true(std::fabs(many.vertex_mm[0] - once.max_mm) < 1e-6); // the vertex off the surface
	assert_true(std::fabs(many.vertex_mm.back() - many.vertex_mm[0]) < 1e-6);
	assert_true(std::fabs(many.vertex_mm[5000] - 0.2) < 0.01);
}

// evaluate --missing: a missed point takes the furthest reason over the pairs that see it. Pair
// (0, 1) "rectifies" onto camera 0's own image: its left half says rim, its right half kept, and
// its cloud holds the truth where y > 40 mm; pair (1, 2) says no prior everywhere.
static void test_attribute_missing(void **)
{
	const recon::Mesh truth = sphere(85);
	recon::Mesh half = sphere(85.2);
	half.triangles.resize(half.triangles.size() / 2);
	const std::vector<CameraModel> cams = synth::ring();
	eval::EvalResult r;
	assert_true(eval::evaluate(half, truth, cams, {}, eval::EvalParams(), &r).ok());
	eval::PairTrace t01, t12;
	t01.cam_a = 0;
	t01.cam_b = 1;
	const cv::Matx33d &k = cams[0].K;
	const cv::Matx33d kr = k * cams[0].R;
	const cv::Vec3d kt = k * cams[0].T;
	t01.world_to_left = cv::Matx34d(kr(0, 0), kr(0, 1), kr(0, 2), kt[0], kr(1, 0), kr(1, 1), kr(1, 2), kt[1],
					kr(2, 0), kr(2, 1), kr(2, 2), kt[2]);
	t01.reason = cv::Mat(cams[0].size, CV_8U, cv::Scalar(recon::kReasonKept));
	t01.reason.colRange(0, 800).setTo(recon::kReasonRim);
	for (const cv::Point3f &q : truth.positions)
		if (q.y > 40)
			t01.cloud.push_back(q * 1.001f);
	t12 = t01;
	t12.cam_a = 1;
	t12.cam_b = 2;
	t12.reason = cv::Mat(cams[1].size, CV_8U, cv::Scalar(recon::kReasonNoPrior));
	t12.cloud.clear();
	const std::vector<signed char> why = eval::attribute_missing(truth, r, cams, {t01, t12}, eval::EvalParams());
	const std::vector<cv::Point3f> normals = recon::vertex_normals(truth.positions, truth.triangles);
	std::vector<std::vector<char>> seen;
	for (int c = 0; c < 3; ++c)
		seen.push_back(eval::seen_by(cams[size_t(c)], truth, normals, eval::EvalParams()));
	std::vector<int> count(eval::kMissReasons, 0);
	for (size_t i = 0; i < why.size(); ++i) {
		if (r.truth_status[i] != 0) {
			assert_int_equal(why[i], -1);
			continue;
		}
		int want = eval::kMissNoPair;
		if (seen[0][i] && seen[1][i]) {
			const cv::Vec3d x = t01.world_to_left * cv::Vec4d(truth.positions[i].x, truth.positions[i].y,
									   truth.positions[i].z, 1);
			const long u = std::lround(x[0] / x[2]), v = std::lround(x[1] / x[2]);
			// Out of the pinhole's frame (the cameras' distortion brings a few in): no prior.
			const bool in = u >= 0 && v >= 0 && u < 1600 && v < 1200;
			want = !in ? int(recon::kReasonNoPrior) : u < 800 ? int(recon::kReasonRim) : truth.positions[i].y > 40 ? int(eval::kMissFused) : int(eval::kMissOff);
		} else if (seen[1][i] && seen[2][i]) {
			want = recon::kReasonNoPrior;
		}
		assert_int_equal(why[i], want);
		count[size_t(why[i])]++;
	}
	std::printf("truth %zu, missed: no pair %d, no prior %d, rim %d, off %d, fused %d\n", why.size(), count[0], count[1],
		    count[recon::kReasonRim], count[eval::kMissOff], count[eval::kMissFused]);
	for (int k2 : {0, 1, int(recon::kReasonRim), int(eval::kMissOff), int(eval::kMissFused)})
		assert_true(count[size_t(k2)] > 0);
}

// sphere()'s grid: vertex (row j, column i) is j * (nu + 1) + i.
static constexpr int kNu = 120, kNv = 80;

// The face: rows 30-60 (elevation -15..30 deg), columns 30-90 (azimuth -40..40 deg) of sphere().
static bool on_face(int j, int i)
{
	return j >= 30 && j <= 60 && i >= 30 && i <= 90;
}

// The truth's face as simulate writes ground_truth_face.ply: its vertices, the triangles among them.
static recon::Mesh face_of(const recon::Mesh &truth)
{
	recon::Mesh face;
	std::vector<int> index(truth.positions.size(), -1);
	for (int j = 0; j <= kNv; ++j)
		for (int i = 0; i <= kNu; ++i)
			if (on_face(j, i)) {
				index[size_t(j * (kNu + 1) + i)] = int(face.positions.size());
				face.positions.push_back(truth.positions[size_t(j * (kNu + 1) + i)]);
			}
	for (const cv::Vec3i &t : truth.triangles)
		if (index[size_t(t[0])] >= 0 && index[size_t(t[1])] >= 0 && index[size_t(t[2])] >= 0)
			face.triangles.emplace_back(index[size_t(t[0])], index[size_t(t[1])], index[size_t(t[2])]);
	return face;
}

// Face completeness has a known answer: the reconstruction is the truth 0.2 mm out, but only its
// rows >= 40 (the truth's rows are 2.2 mm apart, so row 39 is > 1 mm from it). Every face point
// is counted (the ring sees them all), so the face completeness is the face's rows 40-60 of its
// 30-60: 21 / 31; the whole-head figures are those without the face.
static void test_face_completeness(void **)
{
	const recon::Mesh truth = sphere(85);
	const recon::Mesh full = sphere(85.2);
	recon::Mesh part;
	std::vector<int> index(full.positions.size(), -1);
	for (size_t k = 0; k < full.positions.size(); ++k)
		if (int(k) / (kNu + 1) >= 40) {
			index[k] = int(part.positions.size());
			part.positions.push_back(full.positions[k]);
		}
	for (const cv::Vec3i &t : full.triangles)
		if (index[size_t(t[0])] >= 0 && index[size_t(t[1])] >= 0 && index[size_t(t[2])] >= 0)
			part.triangles.emplace_back(index[size_t(t[0])], index[size_t(t[1])], index[size_t(t[2])]);

	std::vector<char> face;
	assert_true(eval::match_face_vertices(truth, face_of(truth), &face).ok());
	assert_int_equal(face.size(), truth.positions.size());
	int marked = 0;
	for (size_t k = 0; k < face.size(); ++k) {
		assert_int_equal(face[k], on_face(int(k) / (kNu + 1), int(k) % (kNu + 1)));
		marked += face[k];
	}
	assert_int_equal(marked, 31 * 61);

	eval::EvalResult head, r;
	assert_true(eval::evaluate(part, truth, synth::ring(), {}, eval::EvalParams(), &head).ok());
	eval::EvalParams params;
	params.truth_face = face;
	assert_true(eval::evaluate(part, truth, synth::ring(), {}, params, &r).ok());
	std::printf("face: %.4f of %d counted (of %d face points; want 21/31 = %.4f), %d vertices near it; "
		    "whole head: %.4f of %d, %d vertices near it\n",
		    r.face_completeness, r.face_counted, r.face_truth_points, 21.0 / 31, r.face_region_vertices,
		    r.completeness, r.truth_counted, r.face_vertices);
	assert_int_equal(r.face_truth_points, 31 * 61);
	assert_int_equal(r.face_counted, r.face_truth_points);
	assert_true(std::fabs(r.face_completeness - 21.0 / 31) < 1e-12);
	// The whole-head figures are what they were without a face; without one no face figures.
	assert_true(r.completeness == head.completeness && r.truth_counted == head.truth_counted &&
		    r.face_vertices == head.face_vertices && r.rms_mm == head.rms_mm);
	assert_true(head.face_truth_points == 0 && head.face_counted == 0 && head.face_completeness == 0 &&
		    head.face_region_vertices == 0);
	assert_true(std::fabs(r.completeness - r.face_completeness) > 0.05); // not the whole head's figure
	// Face-region vertices: at least the reconstruction's own face rows (each 0.2 mm from its
	// face point), none beyond the 3 x 3 x 3 cells of 2 mm round a face point (< 7 mm).
	int lo = 0, hi = 0;
	for (size_t k = 0; k < part.positions.size(); ++k) {
		const int j = 40 + int(k) / (kNu + 1), i = int(k) % (kNu + 1);
		lo += on_face(j, i);
		bool near = false;
		for (size_t t = 0; t < truth.positions.size() && !near; ++t)
			near = face[t] && cv::norm(part.positions[k] - truth.positions[t]) < 7.0;
		hi += near;
	}
	std::printf("face-region vertices %d, between %d and %d\n", r.face_region_vertices, lo, hi);
	assert_true(r.face_region_vertices >= lo && r.face_region_vertices <= hi);
	assert_true(r.face_region_vertices < r.face_vertices);
	// A face that is not one mark per truth vertex is refused.
	params.truth_face.pop_back();
	assert_int_equal(eval::evaluate(part, truth, synth::ring(), {}, params, &r).code(), -EINVAL);
}

struct TmpDir {
	std::string path;
	TmpDir()
	{
		char t[] = "/tmp/facescan-eval-XXXXXX";
		const char *p = mkdtemp(t);
		assert_non_null(p);
		path = p;
	}
	~TmpDir()
	{
		const std::string cmd = "rm -rf '" + path + "'";
		if (std::system(cmd.c_str()) != 0)
			std::fprintf(stderr, "cannot remove %s\n", path.c_str());
	}
	std::string operator/(const std::string &f) const { return path + "/" + f; }
};

// read_ground_truth's face: absent is no face (older sets), the simulator's subset is marked, and
// a malformed file, a face of another head, an empty one, a FIFO or a directory are refused.
static void test_read_face_file(void **)
{
	const recon::Mesh truth = sphere(85);
	TmpDir d;
	assert_true(mesh_io::write_ply(d / "ground_truth.ply", truth).ok());
	recon::Mesh gt;
	std::vector<CameraModel> projectors;
	std::vector<std::vector<cv::Point2d>> masks;
	std::vector<char> face(3, 1);
	assert_true(eval::read_ground_truth(d.path, &gt, &projectors, &masks, &face).ok());
	assert_true(face.empty());
	assert_int_equal(gt.positions.size(), truth.positions.size());

	assert_true(mesh_io::write_ply(d / "ground_truth_face.ply", face_of(truth)).ok());
	assert_true(eval::read_ground_truth(d.path, &gt, &projectors, &masks, &face).ok());
	assert_int_equal(face.size(), truth.positions.size());
	for (size_t k = 0; k < face.size(); ++k)
		assert_int_equal(face[k], on_face(int(k) / (kNu + 1), int(k) % (kNu + 1)));

	// Refusals: a non-zero code other than -ENOENT, the file named, `ret_face` untouched.
	auto refused = [&](const char *what, const char *needle) {
		std::vector<char> kept(5, 7);
		const Status st = eval::read_ground_truth(d.path, &gt, &projectors, &masks, &kept);
		std::printf("%s: %d %s\n", what, st.code(), st.message().c_str());
		assert_true(st.code() < 0 && st.code() != -ENOENT);
		assert_non_null(std::strstr(st.message().c_str(), "ground_truth_face.ply"));
		assert_non_null(std::strstr(st.message().c_str(), needle));
		assert_true(kept == std::vector<char>(5, 7));
	};
	std::ofstream(d / "ground_truth_face.ply") << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n";
	refused("cut short", "");
	std::ofstream(d / "ground_truth_face.ply") << "not a ply at all";
	refused("not a PLY", "");
	recon::Mesh moved = face_of(truth);
	moved.positions[100].x += 0.01f; // another head's face: one vertex the truth does not have
	assert_true(mesh_io::write_ply(d / "ground_truth_face.ply", moved).ok());
	refused("a vertex off the truth", "1 of the face's");
	std::ofstream(d / "ground_truth_face.ply")
		<< "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
		   "element face 0\nproperty list uchar int vertex_indices\nend_header\n";
	refused("no vertices", "");
	unlink((d / "ground_truth_face.ply").c_str());
	assert_int_equal(mkfifo((d / "ground_truth_face.ply").c_str(), 0644), 0);
	alarm(20); // a reader waiting on the FIFO fails the test instead of stalling the suite
	refused("a FIFO", "not a regular file");
	alarm(0);
	unlink((d / "ground_truth_face.ply").c_str());
	assert_int_equal(mkdir((d / "ground_truth_face.ply").c_str(), 0755), 0);
	refused("a directory", "not a regular file");
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_point_triangle_distance),
		cmocka_unit_test(test_offset_surface),
		cmocka_unit_test(test_duplicates_count_once),
		cmocka_unit_test(test_attribute_missing),
		cmocka_unit_test(test_face_completeness),
		cmocka_unit_test(test_read_face_file),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
