// Stage 4: correspondence between two cameras by cell id, checked against the epipolar
// constraint and a plausible depth. The three projectors throw the same slide, so a cell id can
// appear up to three times in each camera; a square is matched only when exactly one candidate of
// the other camera is geometrically consistent, and one square never takes two partners.
#include "recon/image_stages.hpp"

#include <opencv2/calib3d.hpp>

#include <cmath>
#include <map>
#include <unordered_map>

namespace facescan::recon {

namespace {

// Normalised (undistorted) image coordinates of every feature of every square.
std::vector<cv::Point2d> normalised(const CameraDetections &d, const CameraModel &cam)
{
	std::vector<cv::Point2d> px;
	px.reserve(d.squares.size() * kFeatureCount);
	for (const Square &s : d.squares) {
		px.push_back(s.centroid);
		for (int k = 0; k < 4; k++)
			px.push_back(s.has_corners ? s.corners[size_t(k)] : s.centroid);
	}
	std::vector<cv::Point2d> out;
	if (!px.empty())
		cv::undistortPoints(px, out, cv::Mat(cam.K), cv::Mat(cam.dist));
	return out;
}

struct Geometry {
	cv::Matx33d E, R; // x_b = R x_a + t
	cv::Vec3d t;
	double fa, fb;

	// Symmetric distance to the epipolar lines, pixels.
	double epipolar(const cv::Point2d &na, const cv::Point2d &nb) const
	{
		cv::Vec3d xa(na.x, na.y, 1), xb(nb.x, nb.y, 1);
		cv::Vec3d lb = E * xa, la = E.t() * xb;
		double e = xb.dot(lb);
		double db = std::abs(e) / std::max(1e-12, std::hypot(lb[0], lb[1]));
		double da = std::abs(e) / std::max(1e-12, std::hypot(la[0], la[1]));
		return 0.5 * (da * fa + db * fb);
	}
	// Depth in camera a of the midpoint of the two rays; false when behind either camera.
	bool depth(const cv::Point2d &na, const cv::Point2d &nb, double *ret) const
	{
		cv::Vec3d da(na.x, na.y, 1), ob = -(R.t() * t), db = R.t() * cv::Vec3d(nb.x, nb.y, 1);
		double a = da.dot(da), b = da.dot(db), c = db.dot(db);
		cv::Vec3d w = -ob;
		double d = da.dot(w), e = db.dot(w);
		double den = a * c - b * b;
		if (std::abs(den) < 1e-12)
			return false;
		double s = (b * e - c * d) / den, u = (a * e - b * d) / den;
		if (s <= 0 || u <= 0)
			return false;
		cv::Vec3d p = 0.5 * (s * da + (ob + u * db));
		*ret = p[2];
		return true;
	}
};

// Connected parts of a camera's decoded grid: squares linked by neighbours whose cells agree.
std::vector<int> grid_parts(const CameraDetections &d, int cols)
{
	constexpr int dr[4] = {-1, 0, 0, 1}, dc[4] = {0, -1, 1, 0};
	std::vector<int> part(d.squares.size(), -1);
	int next = 0;
	for (size_t s = 0; s < d.squares.size(); s++) {
		if (part[s] >= 0 || d.squares[s].cell < 0)
			continue;
		std::vector<int> stack{int(s)};
		part[s] = next;
		while (!stack.empty()) {
			const Square &q = d.squares[size_t(stack.back())];
			stack.pop_back();
			for (int k = 0; k < 4; k++) {
				int j = q.neighbours[size_t(k)];
				if (j < 0 || part[size_t(j)] >= 0)
					continue;
				int want = (q.cell / cols + dr[k]) * cols + q.cell % cols + dc[k];
				if (d.squares[size_t(j)].cell != want)
					continue;
				part[size_t(j)] = next;
				stack.push_back(j);
			}
		}
		next++;
	}
	return part;
}

// Growing the matches along the grid (stage 4b). The code only serves to find where a square
// is in the other view; once a square is matched, its grid neighbour in direction d in camera a
// and the neighbour in direction d of its partner in camera b are the same projected square
// whether or not its own code word could be read — a square with a missing neighbour, a dim or
// mixed colour (a projector seam), a slide border cell. Such a candidate is taken when the
// geometry agrees (epipolar line, plausible depth, corners), its letters and cells do not
// contradict, and every neighbour already matched points to the same square in b.
template <typename AddMatch>
void grow_matches(const CameraDetections &a, const CameraDetections &b, const Geometry &g,
		  const std::vector<cv::Point2d> &na, const std::vector<cv::Point2d> &nb,
		  const MatchParams &params, std::vector<size_t> queue, std::vector<int> *match_of_a,
		  std::vector<int> *match_of_b, AddMatch add_square_match, PairMatches *out)
{
	auto consistent = [&](size_t i, int j) {
		const Square &sa = a.squares[i], &sb = b.squares[size_t(j)];
		// A square flagged irregular in both views is cut or bent in both; in one view only, it is
		// usually bent over a curve (lip, nose) there, and its centroid still pins it.
		if (sa.irregular && sb.irregular)
			return false;
		if (sa.cell >= 0 && sb.cell >= 0 && sa.cell != sb.cell)
			return false;
		if (sa.letter >= 0 && sb.letter >= 0 && sa.letter != sb.letter)
			return false;
		const cv::Point2d &pa = na[i * kFeatureCount], &pb = nb[size_t(j) * kFeatureCount];
		double z = 0;
		if (g.epipolar(pa, pb) > params.grow_max_epipolar_px || !g.depth(pa, pb, &z) ||
		    z < params.min_depth_mm || z > params.max_depth_mm)
			return false;
		// Topology: every matched neighbour of i must be matched to j's neighbour on that side.
		int support = 0;
		for (int d = 0; d < 4; d++) {
			const int ia = sa.neighbours[size_t(d)];
			if (ia < 0 || (*match_of_a)[size_t(ia)] < 0)
				continue;
			if ((*match_of_a)[size_t(ia)] != sb.neighbours[size_t(d)])
				return false;
			support++;
		}
		return support >= 1;
	};
	while (!queue.empty()) {
		const size_t i = queue.back();
		queue.pop_back();
		const int j = (*match_of_a)[i];
		for (int d = 0; d < 4; d++) {
			const int i2 = a.squares[i].neighbours[size_t(d)], j2 = b.squares[size_t(j)].neighbours[size_t(d)];
			if (i2 < 0 || j2 < 0 || (*match_of_a)[size_t(i2)] >= 0 || (*match_of_b)[size_t(j2)] >= 0)
				continue;
			if (!consistent(size_t(i2), j2) || !add_square_match(size_t(i2), j2, true))
				continue;
			out->grown++;
			queue.push_back(size_t(i2));
		}
	}
}

} // namespace

Status match_pair(const CameraDetections &a, const CameraDetections &b, const CameraModel &ca,
		  const CameraModel &cb, const Pattern &pattern, const MatchParams &params,
		  PairMatches *ret)
{
	if (ca.K(0, 0) <= 0 || cb.K(0, 0) <= 0 || ca.K(1, 1) <= 0 || cb.K(1, 1) <= 0)
		return Status::error(EINVAL, "match_pair: camera intrinsics have no focal length");
	const int cells = pattern.matrix.rows() * pattern.matrix.cols();
	Geometry g;
	g.R = cb.R * ca.R.t();
	g.t = cb.T - g.R * ca.T;
	if (cv::norm(g.t) < 1e-9)
		return Status::error(EINVAL, "match_pair: the two cameras share their centre");
	cv::Matx33d tx(0, -g.t[2], g.t[1], g.t[2], 0, -g.t[0], -g.t[1], g.t[0], 0);
	g.E = tx * g.R;
	g.fa = 0.5 * (ca.K(0, 0) + ca.K(1, 1));
	g.fb = 0.5 * (cb.K(0, 0) + cb.K(1, 1));
	std::vector<cv::Point2d> na = normalised(a, ca), nb = normalised(b, cb);

	std::unordered_map<int, std::vector<int>> by_cell;
	for (size_t j = 0; j < b.squares.size(); j++)
		if (b.squares[j].cell >= 0 && b.squares[j].cell < cells && !b.squares[j].irregular)
			by_cell[b.squares[j].cell].push_back(int(j));
	const int cols = pattern.matrix.cols();
	std::vector<int> comp_a = grid_parts(a, cols), comp_b = grid_parts(b, cols);

	// Every same-cell candidate, with its geometric verdict, tallied per pair of grid parts.
	struct Cand {
		int i, j;
		bool ok;
	};
	std::vector<Cand> cands;
	std::map<std::pair<int, int>, std::pair<int, int>> tally; // (part a, part b) → (ok, total)
	for (size_t i = 0; i < a.squares.size(); i++) {
		int cell = a.squares[i].cell;
		if (cell < 0 || a.squares[i].irregular)
			continue;
		auto it = by_cell.find(cell);
		if (it == by_cell.end())
			continue;
		for (int j : it->second) {
			const cv::Point2d &pa = na[i * kFeatureCount], &pb = nb[size_t(j) * kFeatureCount];
			double z = 0;
			bool ok = g.epipolar(pa, pb) <= params.max_epipolar_px && g.depth(pa, pb, &z) &&
				  z >= params.min_depth_mm && z <= params.max_depth_mm;
			cands.push_back({int(i), j, ok});
			auto &t = tally[{comp_a[i], comp_b[size_t(j)]}];
			t.first += ok;
			t.second++;
		}
	}
	// A part of the grid in a and one in b show the same copy of the slide when most of the
	// cells they share are geometrically consistent; a wrong copy fails on most of them (the
	// copies lie on different parts of the face, so their rows do not share epipolar lines).
	auto same_copy = [&](int pa, int pb) {
		const auto &t = tally[{pa, pb}];
		return t.first >= std::min(params.min_part_support, t.second) &&
		       t.first >= params.min_part_agreement * t.second;
	};
	PairMatches out;
	out.cam_a = a.camera;
	out.cam_b = b.camera;
	std::vector<int> partner(a.squares.size(), -1), valid(a.squares.size(), 0), seen(a.squares.size(), 0);
	std::vector<int> taken(b.squares.size(), 0);
	for (const Cand &c : cands) {
		seen[size_t(c.i)]++;
		if (!c.ok || !same_copy(comp_a[size_t(c.i)], comp_b[size_t(c.j)]))
			continue;
		valid[size_t(c.i)]++;
		partner[size_t(c.i)] = c.j;
	}
	for (size_t i = 0; i < a.squares.size(); i++) {
		if (!seen[i])
			continue;
		if (valid[i] == 0) {
			out.rejected_epipolar++;
			partner[i] = -1;
		} else if (valid[i] > 1) {
			out.rejected_ambiguous++;
			partner[i] = -1;
		} else {
			taken[size_t(partner[i])]++;
		}
	}
	// The square pair (i, j) as matches (centroid, and corners when both views have them), or
	// false when a corner is off its epipolar line: a square cut differently in the two views
	// (an occluding contour, a shadow seen from one side) is not the same surface patch, so
	// none of its features is trusted.
	std::vector<int> match_of_a(a.squares.size(), -1), match_of_b(b.squares.size(), -1);
	auto add_square_match = [&](size_t i, int j, bool grown) {
		const Square &sa = a.squares[i], &sb = b.squares[size_t(j)];
		const bool corners = params.corners && sa.has_corners && sb.has_corners;
		for (int k = 0; corners && k < 4; k++) {
			size_t fa = i * kFeatureCount + size_t(k) + 1, fb = size_t(j) * kFeatureCount + size_t(k) + 1;
			if (g.epipolar(na[fa], nb[fb]) > params.max_corner_epipolar_px)
				return false;
		}
		PointMatch pm;
		pm.square_a = int(i);
		pm.square_b = j;
		pm.cell = sa.cell >= 0 ? sa.cell : sb.cell;
		pm.grown = grown;
		pm.feature = kCentroid;
		pm.a = sa.centroid;
		pm.b = sb.centroid;
		out.matches.push_back(pm);
		for (int k = 0; corners && k < 4; k++) {
			pm.feature = kTopLeft + k;
			pm.a = sa.corners[size_t(k)];
			pm.b = sb.corners[size_t(k)];
			out.matches.push_back(pm);
		}
		match_of_a[i] = j;
		match_of_b[size_t(j)] = int(i);
		return true;
	};
	std::vector<size_t> seeds;
	for (size_t i = 0; i < a.squares.size(); i++) {
		int j = partner[i];
		if (j < 0)
			continue;
		if (taken[size_t(j)] > 1) { // two copies in a claim one square in b
			out.rejected_ambiguous++;
			continue;
		}
		if (!add_square_match(i, j, false)) {
			out.rejected_epipolar++;
			continue;
		}
		seeds.push_back(i);
	}
	if (params.grow)
		grow_matches(a, b, g, na, nb, params, seeds, &match_of_a, &match_of_b, add_square_match, &out);
	*ret = std::move(out);
	return {};
}

} // namespace facescan::recon
