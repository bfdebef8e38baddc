// Reconstruction accuracy metrics. See eval.hpp.
#include "eval/eval.hpp"
#include "mesh_io/mesh_io.hpp"
#include "recon/dense.hpp"
#include "recon/fusion.hpp"
#include "recon/raster.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <tuple>
#include <unordered_map>
#include <unordered_set>

#include <unistd.h>

namespace facescan::eval {

double point_triangle_distance(const cv::Point3d &p, const cv::Point3d &a, const cv::Point3d &b,
			       const cv::Point3d &c)
{
	const cv::Point3d ab = b - a, ac = c - a, ap = p - a;
	const double d1 = ab.dot(ap), d2 = ac.dot(ap);
	if (d1 <= 0 && d2 <= 0)
		return cv::norm(p - a);
	const cv::Point3d bp = p - b;
	const double d3 = ab.dot(bp), d4 = ac.dot(bp);
	if (d3 >= 0 && d4 <= d3)
		return cv::norm(p - b);
	const double vc = d1 * d4 - d3 * d2;
	if (vc <= 0 && d1 >= 0 && d3 <= 0)
		return cv::norm(p - (a + ab * (d1 / (d1 - d3))));
	const cv::Point3d cp = p - c;
	const double d5 = ab.dot(cp), d6 = ac.dot(cp);
	if (d6 >= 0 && d5 <= d6)
		return cv::norm(p - c);
	const double vb = d5 * d2 - d1 * d6;
	if (vb <= 0 && d2 >= 0 && d6 <= 0)
		return cv::norm(p - (a + ac * (d2 / (d2 - d6))));
	const double va = d3 * d6 - d5 * d4;
	if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
		return cv::norm(p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))));
	const double denom = 1.0 / (va + vb + vc);
	return cv::norm(p - (a + ab * (vb * denom) + ac * (vc * denom)));
}

struct MeshDistance::Impl {
	std::vector<cv::Point3d> v;
	std::vector<cv::Vec3i> t;
	double cell = 1;
	std::unordered_map<int64_t, std::vector<int>> grid;
	static int64_t key(int64_t x, int64_t y, int64_t z)
	{
		return ((x + (1 << 20)) << 42) | ((y + (1 << 20)) << 21) | (z + (1 << 20));
	}
	int64_t coord(double x) const { return int64_t(std::floor(x / cell)); }
};

MeshDistance::MeshDistance(const std::vector<cv::Point3f> &positions, const std::vector<cv::Vec3i> &triangles,
			   double cell_mm)
	: impl_(std::make_unique<Impl>())
{
	impl_->v.assign(positions.begin(), positions.end());
	impl_->t = triangles;
	impl_->cell = std::max(cell_mm, 1e-3);
	for (size_t i = 0; i < triangles.size(); ++i) {
		const cv::Vec3i &tri = triangles[i];
		cv::Point3d lo = impl_->v[size_t(tri[0])], hi = lo;
		for (int k = 1; k < 3; ++k) {
			const cv::Point3d &p = impl_->v[size_t(tri[k])];
			lo = cv::Point3d(std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z));
			hi = cv::Point3d(std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z));
		}
		for (int64_t x = impl_->coord(lo.x); x <= impl_->coord(hi.x); ++x)
			for (int64_t y = impl_->coord(lo.y); y <= impl_->coord(hi.y); ++y)
				for (int64_t z = impl_->coord(lo.z); z <= impl_->coord(hi.z); ++z)
					impl_->grid[Impl::key(x, y, z)].push_back(int(i));
	}
}

MeshDistance::~MeshDistance() = default;

double MeshDistance::distance(const cv::Point3d &p, double max_mm) const
{
	const Impl &m = *impl_;
	const int64_t cx = m.coord(p.x), cy = m.coord(p.y), cz = m.coord(p.z);
	double best = std::numeric_limits<double>::infinity();
	const int64_t reach = int64_t(std::ceil(max_mm / m.cell));
	// Grow shells of cells until the nearest hit is closer than the shell's inner distance.
	for (int64_t r = 0; r <= reach; ++r) {
		if (best <= double(r - 1) * m.cell)
			break;
		for (int64_t x = cx - r; x <= cx + r; ++x)
			for (int64_t y = cy - r; y <= cy + r; ++y)
				for (int64_t z = cz - r; z <= cz + r; ++z) {
					if (std::max({std::llabs(x - cx), std::llabs(y - cy), std::llabs(z - cz)}) != r)
						continue;
					auto it = m.grid.find(Impl::key(x, y, z));
					if (it == m.grid.end())
						continue;
					for (int ti : it->second) {
						const cv::Vec3i &t = m.t[size_t(ti)];
						best = std::min(best, point_triangle_distance(p, m.v[size_t(t[0])],
											   m.v[size_t(t[1])],
											   m.v[size_t(t[2])]));
					}
				}
	}
	return best <= max_mm ? best : std::numeric_limits<double>::infinity();
}

// The slide masks a simulated set records next to its projectors (absent = whole slides).
static Status read_slide_masks(const std::string &path, size_t projectors,
			       std::vector<std::vector<cv::Point2d>> *ret_masks)
{
	std::vector<std::vector<cv::Point2d>> masks(projectors);
	try {
		cv::FileStorage fs(path, cv::FileStorage::READ);
		for (size_t j = 0; j < projectors; ++j) {
			const std::string key = "cam" + std::to_string(j) + "_slide_mask";
			const cv::FileNode n = fs[key];
			if (n.empty())
				continue;
			if (!n.isSeq() || n.size() < 6 || n.size() % 2)
				return Status::error(-EINVAL, path + ": field '" + key +
								      "' must be a list x0, y0, x1, y1, ... of at least 3 points");
			for (size_t k = 0; k < n.size(); k += 2) {
				if (!n[int(k)].isReal() && !n[int(k)].isInt())
					return Status::error(-EINVAL, path + ": field '" + key + "' holds a non-number");
				masks[j].emplace_back(double(n[int(k)]), double(n[int(k + 1)]));
			}
		}
	} catch (const cv::Exception &e) {
		return Status::error(-EINVAL, path + ": " + e.msg);
	}
	*ret_masks = std::move(masks);
	return {};
}

namespace {
// A vertex position by its floats' bits (-0 folded into +0): ground_truth.ply and
// ground_truth_face.ply are written from the same floats, so the face's vertices are found exactly.
struct PositionKey {
	uint32_t x, y, z;
	bool operator==(const PositionKey &o) const { return x == o.x && y == o.y && z == o.z; }
};
struct PositionHash {
	size_t operator()(const PositionKey &k) const
	{
		return (size_t(k.x) * 73856093u) ^ (size_t(k.y) * 19349663u) ^ (size_t(k.z) * 83492791u);
	}
};
PositionKey position_key(const cv::Point3f &p)
{
	const float f[3] = {p.x + 0.0f, p.y + 0.0f, p.z + 0.0f};
	PositionKey k;
	std::memcpy(&k.x, &f[0], sizeof k.x);
	std::memcpy(&k.y, &f[1], sizeof k.y);
	std::memcpy(&k.z, &f[2], sizeof k.z);
	return k;
}
} // namespace

Status match_face_vertices(const recon::Mesh &truth, const recon::Mesh &face, std::vector<char> *ret_face)
{
	if (face.positions.empty())
		return Status::error(-EINVAL, "the face has no vertices");
	// Face position -> whether a truth vertex has it.
	std::unordered_map<PositionKey, char, PositionHash> found;
	found.reserve(face.positions.size());
	for (const cv::Point3f &p : face.positions)
		found.emplace(position_key(p), 0);
	std::vector<char> marks(truth.positions.size(), 0);
	for (size_t i = 0; i < truth.positions.size(); ++i) {
		const auto it = found.find(position_key(truth.positions[i]));
		if (it == found.end())
			continue;
		marks[i] = 1;
		it->second = 1;
	}
	size_t strays = 0;
	for (const auto &kv : found)
		strays += !kv.second;
	if (strays)
		return Status::error(-EINVAL, std::to_string(strays) + " of the face's " + std::to_string(found.size()) +
						      " vertex positions are not vertices of the truth (not this head's face)");
	*ret_face = std::move(marks);
	return {};
}

Status read_ground_truth(const std::string &capture_dir, recon::Mesh *ret_truth,
			 std::vector<CameraModel> *ret_projectors,
			 std::vector<std::vector<cv::Point2d>> *ret_masks, std::vector<char> *ret_face)
{
	const std::string mesh_path = capture_dir + "/ground_truth.ply";
	const std::string projectors_path = capture_dir + "/ground_truth_projectors.yaml";
	if (access(mesh_path.c_str(), F_OK) != 0)
		return Status::error(-ENOENT, mesh_path + ": no ground truth (not a simulated capture set)");
	recon::Mesh truth;
	Status s = mesh_io::read_ply(mesh_path, &truth);
	Calibration projectors;
	std::vector<std::vector<cv::Point2d>> masks;
	if (s.ok() && access(projectors_path.c_str(), F_OK) == 0) {
		s = read_calibration(projectors_path, &projectors);
		if (s.ok() && ret_masks)
			s = read_slide_masks(projectors_path, projectors.cameras.size(), &masks);
	}
	// The face region (sets rendered before it was written have none: no face figures).
	std::vector<char> face_marks;
	if (s.ok() && ret_face) {
		const std::string face_path = capture_dir + "/ground_truth_face.ply";
		recon::Mesh face;
		s = mesh_io::read_ply(face_path, &face);
		if (s.code() == -ENOENT)
			s = {};
		else if (s.ok()) {
			s = match_face_vertices(truth, face, &face_marks);
			if (!s.ok())
				s = Status::error(s.code(), face_path + ": " + s.message());
		}
	}
	if (!s.ok())
		return s;
	*ret_truth = std::move(truth);
	*ret_projectors = std::move(projectors.cameras);
	if (ret_masks)
		*ret_masks = std::move(masks);
	if (ret_face)
		*ret_face = std::move(face_marks);
	return {};
}

std::vector<char> seen_by(const CameraModel &device, const recon::Mesh &mesh, const std::vector<cv::Point3f> &normals,
			  const EvalParams &params, const std::vector<cv::Point2d> &slide_mask)
{
	const std::vector<cv::Point3d> pts(mesh.positions.begin(), mesh.positions.end());
	const cv::Mat depth = recon::render_depth(device, mesh.positions, mesh.triangles, params.depth_scale);
	std::vector<char> v = recon::visible_in(device, depth, params.depth_scale, pts, params.occlusion_tolerance_mm);
	const cv::Vec3d c = device.centre();
	std::vector<cv::Point2f> poly(slide_mask.begin(), slide_mask.end());
	for (size_t i = 0; i < pts.size(); ++i) {
		const cv::Vec3d view = c - cv::Vec3d(pts[i]);
		const cv::Vec3d n(normals[i].x, normals[i].y, normals[i].z);
		if (n.dot(view) < params.min_cos * cv::norm(view))
			v[i] = 0;
		if (v[i] && !poly.empty()) {
			// Only the slide's unmasked part throws light.
			const cv::Vec3d x = device.K * (device.R * cv::Vec3d(pts[i]) + device.T);
			v[i] = x[2] > 0 && cv::pointPolygonTest(poly, cv::Point2f(float(x[0] / x[2]), float(x[1] / x[2])),
								   false) >= 0;
		}
	}
	return v;
}

Status evaluate(const recon::Mesh &recon, const recon::Mesh &truth, const std::vector<CameraModel> &cameras,
		const std::vector<CameraModel> &projectors, const EvalParams &params, EvalResult *ret_result)
{
	if (recon.positions.empty() || recon.triangles.empty())
		return Status::error(-EINVAL, "evaluate: the reconstruction has no triangles");
	if (truth.positions.empty() || truth.triangles.empty())
		return Status::error(-EINVAL, "evaluate: the ground truth has no triangles");
	if (params.projector_masks.size() > projectors.size())
		return Status::error(-EINVAL, "evaluate: more slide masks than projectors");
	if (!params.truth_face.empty() && params.truth_face.size() != truth.positions.size())
		return Status::error(-EINVAL, "evaluate: the face has " + std::to_string(params.truth_face.size()) +
						      " marks for the truth's " + std::to_string(truth.positions.size()) +
						      " vertices");
	const bool has_face = !params.truth_face.empty();
	EvalResult r;
	r.vertices = int(recon.positions.size());
	r.triangles = int(recon.triangles.size());

	// Reconstruction → truth.
	double edge = 0;
	for (const cv::Vec3i &t : truth.triangles)
		edge += cv::norm(truth.positions[size_t(t[0])] - truth.positions[size_t(t[1])]);
	edge /= double(truth.triangles.size());
	const MeshDistance to_truth(truth.positions, truth.triangles, std::max(2.0 * edge, 1.0));
	// Each position once: the texture atlas duplicates a vertex on every chart seam (same
	// position, one UV per chart), which would count a seam's error twice or more.
	std::vector<size_t> order(recon.positions.size());
	for (size_t i = 0; i < order.size(); ++i)
		order[i] = i;
	auto key = [&](size_t i) {
		const cv::Point3f &p = recon.positions[i];
		return std::make_tuple(p.x, p.y, p.z);
	};
	std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return key(a) < key(b); });
	std::vector<double> d;
	d.reserve(order.size());
	double ss = 0;
	r.vertex_mm.assign(order.size(), 0.f);
	for (size_t k = 0; k < order.size(); ++k) {
		if (k > 0 && key(order[k]) == key(order[k - 1])) {
			r.vertex_mm[order[k]] = r.vertex_mm[order[k - 1]];
			continue;
		}
		const double e = std::min(
			to_truth.distance(cv::Point3d(recon.positions[order[k]]), params.max_search_mm),
			params.max_search_mm);
		r.vertex_mm[order[k]] = float(e);
		d.push_back(e);
		ss += e * e;
	}
	r.unique_positions = int(d.size());
	r.rms_mm = std::sqrt(ss / double(d.size()));
	std::sort(d.begin(), d.end());
	r.median_mm = d[d.size() / 2];
	r.p95_mm = d[std::min(d.size() - 1, size_t(0.95 * double(d.size())))];
	r.max_mm = d.back();

	// Which truth points count: seen by >= min_cameras devices, lit by a projector if given.
	std::vector<cv::Point3d> pts(truth.positions.begin(), truth.positions.end());
	const std::vector<cv::Point3f> normals = recon::vertex_normals(truth.positions, truth.triangles);
	std::vector<int> cams_seeing(pts.size(), 0);
	for (const CameraModel &cam : cameras) {
		const std::vector<char> v = seen_by(cam, truth, normals, params);
		for (size_t i = 0; i < pts.size(); ++i)
			cams_seeing[i] += v[i];
	}
	std::vector<char> lit(pts.size(), projectors.empty() ? 1 : 0);
	for (size_t j = 0; j < projectors.size(); ++j) {
		const std::vector<char> v =
			seen_by(projectors[j], truth, normals, params,
				j < params.projector_masks.size() ? params.projector_masks[j] : std::vector<cv::Point2d>());
		for (size_t i = 0; i < pts.size(); ++i)
			lit[i] |= v[i];
	}
	double rec_edge = 0;
	for (const cv::Vec3i &t : recon.triangles)
		rec_edge += cv::norm(recon.positions[size_t(t[0])] - recon.positions[size_t(t[1])]);
	rec_edge /= double(recon.triangles.size());
	const MeshDistance to_recon(recon.positions, recon.triangles, std::max(2.0 * rec_edge, 1.0));
	int covered = 0, face_covered = 0;
	r.truth_points = int(pts.size());
	r.truth_status.assign(pts.size(), -1);
	for (size_t i = 0; i < pts.size(); ++i) {
		const bool on_face = has_face && params.truth_face[i];
		r.face_truth_points += on_face;
		if (cams_seeing[i] < params.min_cameras || !lit[i])
			continue;
		r.truth_counted++;
		r.truth_status[i] = to_recon.distance(pts[i], params.completeness_mm) <= params.completeness_mm;
		covered += r.truth_status[i];
		r.face_counted += on_face;
		face_covered += on_face && r.truth_status[i];
	}
	r.completeness = r.truth_counted ? double(covered) / r.truth_counted : 0;
	r.face_completeness = r.face_counted ? double(face_covered) / r.face_counted : 0;

	// Vertices on the counted surface: within a 2 mm cell (or a neighbouring one) of a counted
	// truth point; for face_region_vertices, of any face truth point: a vertex on the face is on
	// it whether or not the evaluation's visibility test (which gives up on surfaces steeper than
	// ~60 degrees to a camera) counts the truth there. The neck, shoulders or hair a booth also
	// reconstructs do not count, and neither do the texture atlas's copies of a
	// vertex on its chart seams (each position once, as for the RMS: bench booth 1900, 246k
	// vertices for 201k positions).
	auto vertices_near = [&](bool face_only) {
		const double cell = 2.0;
		auto cell_key = [&](const cv::Point3d &p, int dx, int dy, int dz) {
			const long long x = (long long)std::floor(p.x / cell) + dx, y = (long long)std::floor(p.y / cell) + dy,
					z = (long long)std::floor(p.z / cell) + dz;
			return (x * 73856093LL) ^ (y * 19349663LL) ^ (z * 83492791LL);
		};
		std::unordered_set<long long> counted;
		for (size_t i = 0; i < pts.size(); ++i)
			if (face_only ? params.truth_face[i] != 0 : r.truth_status[i] >= 0)
				counted.insert(cell_key(pts[i], 0, 0, 0));
		int n = 0;
		for (size_t k = 0; k < order.size(); ++k) {
			if (k > 0 && key(order[k]) == key(order[k - 1]))
				continue;
			const cv::Point3d v(recon.positions[order[k]]);
			bool near = false;
			for (int j = 0; j < 27 && !near; ++j)
				near = counted.count(cell_key(v, j % 3 - 1, j / 3 % 3 - 1, j / 9 - 1)) > 0;
			n += near;
		}
		return n;
	};
	r.face_vertices = vertices_near(false);
	if (has_face)
		r.face_region_vertices = vertices_near(true);
	*ret_result = r;
	return {};
}

Status read_pair_traces(const std::string &debug_dir, std::vector<PairTrace> *ret_traces)
{
	std::vector<PairTrace> traces;
	for (int p = 0;; ++p) {
		const std::string stem = debug_dir + "/pair" + std::to_string(p);
		if (access((stem + "_rectification.yaml").c_str(), F_OK) != 0)
			break;
		PairTrace t;
		cv::FileStorage fs(stem + "_rectification.yaml", cv::FileStorage::READ);
		cv::Mat m;
		if (fs.isOpened()) {
			fs["cam_a"] >> t.cam_a;
			fs["cam_b"] >> t.cam_b;
			fs["world_to_left"] >> m;
		}
		if (m.rows != 3 || m.cols != 4 || m.type() != CV_64F || t.cam_a < 0 || t.cam_b < 0)
			return Status::error(-EINVAL, stem + "_rectification.yaml: malformed");
		t.world_to_left = cv::Matx34d(m);
		t.reason = cv::imread(stem + "_reasons.png", cv::IMREAD_UNCHANGED);
		if (t.reason.empty() || t.reason.type() != CV_8U)
			return Status::error(-EINVAL, stem + "_reasons.png: missing or not 8-bit grey");
		recon::Mesh cloud;
		if (access((stem + "_dense.ply").c_str(), F_OK) == 0) {
			Status s = mesh_io::read_ply(stem + "_dense.ply", &cloud);
			if (!s.ok())
				return s;
		}
		t.cloud = std::move(cloud.positions);
		traces.push_back(std::move(t));
	}
	if (traces.empty())
		return Status::error(-ENOENT, debug_dir + ": no pair0_rectification.yaml (not a recon --debug directory?)");
	*ret_traces = std::move(traces);
	return {};
}

const char *miss_reason_name(int reason)
{
	static const char *const names[kMissReasons] = {
		"no pair sees it", "no prior",	       "unlit (contrast)", "SGBM refused", "dark",
		"low NCC",	   "search edge",      "near refused",	   "flat dropped", "rim",
		"steep",	   "island",	       "kept, > 1 mm off", "lost in the surface"};
	return reason >= 0 && reason < kMissReasons ? names[reason] : "?";
}

std::vector<signed char> attribute_missing(const recon::Mesh &truth, const EvalResult &result,
					   const std::vector<CameraModel> &cameras,
					   const std::vector<PairTrace> &traces, const EvalParams &params)
{
	const size_t n = truth.positions.size();
	std::vector<signed char> why(n, -1);
	if (result.truth_status.size() != n)
		return why;
	const std::vector<cv::Point3f> normals = recon::vertex_normals(truth.positions, truth.triangles);
	std::vector<std::vector<char>> seen(cameras.size());
	for (size_t c = 0; c < cameras.size(); ++c)
		seen[c] = seen_by(cameras[c], truth, normals, params);
	const double cell = params.completeness_mm;
	auto key = [cell](const cv::Point3f &q) {
		return (int64_t(std::floor(q.x / cell)) * 73856093) ^ (int64_t(std::floor(q.y / cell)) * 19349663) ^
		       (int64_t(std::floor(q.z / cell)) * 83492791);
	};
	for (size_t i = 0; i < n; ++i)
		if (result.truth_status[i] == 0)
			why[i] = kMissNoPair;
	for (const PairTrace &t : traces) {
		if (size_t(std::max(t.cam_a, t.cam_b)) >= cameras.size())
			continue;
		// The cloud by cells of completeness_mm, for "is a point of it that near".
		std::unordered_map<int64_t, std::vector<uint32_t>> grid;
		for (size_t k = 0; k < t.cloud.size(); ++k)
			grid[key(t.cloud[k])].push_back(uint32_t(k));
		auto near_cloud = [&](const cv::Point3f &q) {
			for (int dx = -1; dx <= 1; ++dx)
				for (int dy = -1; dy <= 1; ++dy)
					for (int dz = -1; dz <= 1; ++dz) {
						const cv::Point3f o(q.x + float(dx * cell), q.y + float(dy * cell), q.z + float(dz * cell));
						const auto it = grid.find(key(o));
						if (it == grid.end())
							continue;
						for (uint32_t k : it->second)
							if (cv::norm(t.cloud[k] - q) <= cell)
								return true;
					}
			return false;
		};
		for (size_t i = 0; i < n; ++i) {
			if (why[i] < 0 || !seen[size_t(t.cam_a)][i] || !seen[size_t(t.cam_b)][i])
				continue;
			const cv::Point3f &q = truth.positions[i];
			const cv::Vec3d x = t.world_to_left * cv::Vec4d(q.x, q.y, q.z, 1);
			if (!(x[2] > 0))
				continue;
			const int u = int(std::lround(x[0] / x[2])), v = int(std::lround(x[1] / x[2]));
			int r = recon::kReasonNoPrior;
			if (u >= 0 && v >= 0 && u < t.reason.cols && v < t.reason.rows)
				r = std::max(int(t.reason.at<uchar>(v, u)), int(recon::kReasonNoPrior));
			if (r == recon::kReasonKept)
				r = near_cloud(q) ? kMissFused : kMissOff;
			why[i] = static_cast<signed char>(std::max(int(why[i]), r));
		}
	}
	return why;
}

} // namespace facescan::eval
