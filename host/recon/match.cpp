// Stage 4: correspondence between two cameras by cell id, checked against the epipolar
// constraint and a plausible depth (match_codes), then the squares the code did not match
// (grow_matches, guide_matches, seed_matches) and the pruning of those off their neighbours'
// surface (prune_matches); match_pair composes them. The three projectors throw the same slide,
// so a cell id can appear up to three times in each camera; a square is matched only when exactly
// one candidate of the other camera is geometrically consistent, and one square never takes two
// partners.
#include "recon/image_stages.hpp"

#include <opencv2/calib3d.hpp>

#include <cmath>
#include <map>
#include <string>
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

// Symmetric distance to the epipolar lines, pixels.
double epipolar(const PairGeometry &g, const cv::Point2d &na, const cv::Point2d &nb)
{
	cv::Vec3d xa(na.x, na.y, 1), xb(nb.x, nb.y, 1);
	cv::Vec3d lb = g.E * xa, la = g.E.t() * xb;
	double e = xb.dot(lb);
	double db = std::abs(e) / std::max(1e-12, std::hypot(lb[0], lb[1]));
	double da = std::abs(e) / std::max(1e-12, std::hypot(la[0], la[1]));
	return 0.5 * (da * g.fa + db * g.fb);
}

// True when every corner of square i of camera a lies within max_px of the epipolar line of the
// same corner of square j of camera b (both squares must have corners). A corner is the image of
// one surface point; the area centroid of a square seen obliquely is not.
bool corners_on_lines(const PairGeometry &g, size_t i, size_t j, double max_px)
{
	for (size_t k = 1; k <= 4; k++)
		if (epipolar(g, g.na[i * kFeatureCount + k], g.nb[j * kFeatureCount + k]) > max_px)
			return false;
	return true;
}

// The midpoint of the two rays in camera a's frame, mm; false when behind either camera.
bool ray_point(const PairGeometry &g, const cv::Point2d &na, const cv::Point2d &nb, cv::Vec3d *ret)
{
	cv::Vec3d da(na.x, na.y, 1), ob = -(g.R.t() * g.t), db = g.R.t() * cv::Vec3d(nb.x, nb.y, 1);
	double a = da.dot(da), b = da.dot(db), c = db.dot(db);
	cv::Vec3d w = -ob;
	double d = da.dot(w), e = db.dot(w);
	double den = a * c - b * b;
	if (std::abs(den) < 1e-12)
		return false;
	double s = (b * e - c * d) / den, u = (a * e - b * d) / den;
	if (s <= 0 || u <= 0)
		return false;
	*ret = 0.5 * (s * da + (ob + u * db));
	return true;
}

// Depth in camera a of the midpoint of the two rays; false when behind either camera.
bool ray_depth(const PairGeometry &g, const cv::Point2d &na, const cv::Point2d &nb, double *ret)
{
	cv::Vec3d p;
	if (!ray_point(g, na, nb, &p))
		return false;
	*ret = p[2];
	return true;
}

// -EINVAL unless `g` holds the features of exactly these detections and every match (when given)
// names squares and a feature that exist.
Status check_inputs(const char *who, const CameraDetections &a, const CameraDetections &b,
		    const PairGeometry &g, const PairMatches *pm)
{
	if (g.na.size() != a.squares.size() * kFeatureCount || g.nb.size() != b.squares.size() * kFeatureCount)
		return Status::error(EINVAL, std::string(who) + ": the pair geometry is not of these detections (" +
						     std::to_string(g.na.size()) + " and " + std::to_string(g.nb.size()) +
						     " features for " + std::to_string(a.squares.size()) + " and " +
						     std::to_string(b.squares.size()) + " squares)");
	if (!pm)
		return Status::error(EINVAL, std::string(who) + ": no matches to work on");
	for (const PointMatch &m : pm->matches)
		if (m.square_a < 0 || size_t(m.square_a) >= a.squares.size() || m.square_b < 0 ||
		    size_t(m.square_b) >= b.squares.size() || m.feature < kCentroid || m.feature >= kFeatureCount)
			return Status::error(EINVAL, std::string(who) + ": a match names square " +
							     std::to_string(m.square_a) + " / " + std::to_string(m.square_b) +
							     " feature " + std::to_string(m.feature) +
							     ", not in these detections");
	return {};
}

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

// The matching of one pair as a sub-stage finds it and adds to it: who is matched to whom (from
// the matches so far), and the tests every way of matching a square holds a pair to. Stages 4b-4d
// (see image_stages.hpp): growing, guiding and seeding all pass a candidate through compatible()
// (letters and cells do not contradict, the epipolar line, a plausible depth) and add it through
// add_square() (its corners too, when they agree).
class PairMatcher {
public:
	PairMatcher(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		    const PairCheckParams &check, PairMatches *pm)
		: a_(a), b_(b), g_(g), check_(check), pm_(*pm), match_of_a_(a.squares.size(), -1),
		  match_of_b_(b.squares.size(), -1)
	{
		for (const PointMatch &m : pm->matches) {
			match_of_a_[size_t(m.square_a)] = m.square_b;
			match_of_b_[size_t(m.square_b)] = m.square_a;
		}
	}

	// The square pair (i, j) as matches (centroid, and corners when both views have them), or
	// false when a corner is off its epipolar line: a square cut differently in the two views
	// (an occluding contour, a shadow seen from one side) is not the same surface patch, so
	// none of its features is trusted.
	bool add_square(size_t i, int j, bool grown)
	{
		const Square &sa = a_.squares[i], &sb = b_.squares[size_t(j)];
		const bool corners = check_.corners && sa.has_corners && sb.has_corners;
		if (corners && !corners_on_lines(g_, i, size_t(j), check_.max_corner_epipolar_px))
			return false;
		PointMatch pm;
		pm.square_a = int(i);
		pm.square_b = j;
		pm.cell = sa.cell >= 0 ? sa.cell : sb.cell;
		pm.grown = grown;
		pm.feature = kCentroid;
		pm.a = sa.centroid;
		pm.b = sb.centroid;
		pm_.matches.push_back(pm);
		for (int k = 0; corners && k < 4; k++) {
			pm.feature = kTopLeft + k;
			pm.a = sa.corners[size_t(k)];
			pm.b = sb.corners[size_t(k)];
			pm_.matches.push_back(pm);
		}
		match_of_a_[i] = j;
		match_of_b_[size_t(j)] = int(i);
		return true;
	}

	/// The squares of camera a matched so far, in the order they were matched.
	std::vector<size_t> matched() const
	{
		std::vector<size_t> out;
		std::vector<char> listed(a_.squares.size(), 0);
		for (const PointMatch &m : pm_.matches)
			if (!listed[size_t(m.square_a)]) {
				listed[size_t(m.square_a)] = 1;
				out.push_back(size_t(m.square_a));
			}
		return out;
	}

	/// Grows from the matched squares `queue` of camera a; returns how many it added.
	int grow(std::vector<size_t> queue)
	{
		int added = 0;
		while (!queue.empty()) {
			const size_t i = queue.back();
			queue.pop_back();
			const int j = match_of_a_[i];
			for (int d = 0; d < 4; d++) {
				const int i2 = a_.squares[i].neighbours[size_t(d)];
				const int j2 = b_.squares[size_t(j)].neighbours[size_t(d)];
				if (i2 < 0 || j2 < 0 || match_of_a_[size_t(i2)] >= 0 || match_of_b_[size_t(j2)] >= 0)
					continue;
				if (!topology_agrees(size_t(i2), j2) || !compatible(size_t(i2), j2, nullptr) ||
				    !add_square(size_t(i2), j2, true))
					continue;
				added++;
				queue.push_back(size_t(i2));
			}
		}
		return added;
	}

	/// One round of guided matching; returns how many squares it matched.
	int guide(const GuideParams &params)
	{
		double radius = 0; // in camera a's pixels
		std::vector<double> links;
		for (const Square &s : a_.squares)
			for (int j : s.neighbours)
				if (j >= 0)
					links.push_back(cv::norm(s.centroid - a_.squares[size_t(j)].centroid));
		if (!links.empty()) {
			std::nth_element(links.begin(), links.begin() + long(links.size() / 2), links.end());
			radius = params.radius_pitches * links[links.size() / 2];
		}
		const std::vector<double> depth = matched_depths();
		std::vector<int> choice(a_.squares.size(), -1), chosen_by(b_.squares.size(), 0);
		for (size_t i = 0; i < a_.squares.size(); i++) {
			if (match_of_a_[i] >= 0)
				continue;
			double lo = 1e300, hi = -1e300;
			int around = 0;
			for (size_t k = 0; k < a_.squares.size(); k++)
				if (depth[k] > 0 && cv::norm(a_.squares[k].centroid - a_.squares[i].centroid) <= radius) {
					lo = std::min(lo, depth[k]);
					hi = std::max(hi, depth[k]);
					around++;
				}
			if (around < params.min_around)
				continue;
			int found = -1, count = 0;
			for (size_t j = 0; j < b_.squares.size(); j++) {
				double z = 0;
				if (match_of_b_[j] >= 0 || !compatible(i, int(j), &z) || z < lo - params.depth_margin_mm ||
				    z > hi + params.depth_margin_mm)
					continue;
				found = int(j);
				count++;
			}
			if (count == 1) {
				choice[i] = found;
				chosen_by[size_t(found)]++;
			}
		}
		int added = 0;
		for (size_t i = 0; i < a_.squares.size(); i++)
			if (choice[i] >= 0 && chosen_by[size_t(choice[i])] == 1 && add_square(i, choice[i], true))
				added++;
		return added;
	}

	/// Seeds growth (seed_matches in image_stages.hpp) and grows from each seed at once, adding
	/// to *ret_grown; returns the number of seeds.
	int seed(const SeedParams &params, int *ret_grown)
	{
		double lo = 1e300, hi = -1e300;
		for (double z : matched_depths())
			if (z > 0) {
				lo = std::min(lo, z);
				hi = std::max(hi, z);
			}
		if (lo > hi)
			return 0;
		lo -= params.depth_margin_mm;
		hi += params.depth_margin_mm;
		struct Seed {
			int support;
			size_t i;
			int j;
		};
		std::vector<Seed> seeds;
		for (size_t i = 0; i < a_.squares.size(); i++) {
			if (match_of_a_[i] >= 0 || a_.squares[i].letter < 0)
				continue;
			int best = 0, second = 0, best_j = -1;
			for (size_t j = 0; j < b_.squares.size(); j++) {
				double z = 0;
				if (match_of_b_[j] >= 0 || b_.squares[j].letter < 0 || !compatible(i, int(j), &z) ||
				    z < lo || z > hi)
					continue;
				const int support = dry_grow(i, int(j));
				if (support > best) {
					second = best;
					best = support;
					best_j = int(j);
				} else {
					second = std::max(second, support);
				}
			}
			if (best >= params.min_support && second * 2 < best)
				seeds.push_back({best, i, best_j});
		}
		std::sort(seeds.begin(), seeds.end(), [](const Seed &x, const Seed &y) { return x.support > y.support; });
		int planted = 0;
		for (const Seed &sd : seeds)
			if (match_of_a_[sd.i] < 0 && match_of_b_[size_t(sd.j)] < 0 && add_square(sd.i, sd.j, true)) {
				planted++;
				*ret_grown += grow({sd.i});
			}
		return planted;
	}

private:
	// Depth (camera a, mm) of every matched square's centroid; -1 for the unmatched.
	std::vector<double> matched_depths() const
	{
		std::vector<double> depth(a_.squares.size(), -1);
		for (size_t i = 0; i < a_.squares.size(); i++) {
			const int j = match_of_a_[i];
			double z = 0;
			if (j >= 0 && ray_depth(g_, g_.na[i * kFeatureCount], g_.nb[size_t(j) * kFeatureCount], &z))
				depth[i] = z;
		}
		return depth;
	}

	// How many squares with a known letter in both views growing from the pair (i, j) would
	// match, without matching them.
	int dry_grow(size_t i, int j) const
	{
		std::unordered_map<int, int> pair_of_a{{int(i), j}};
		std::unordered_map<int, int> pair_of_b{{j, int(i)}};
		std::vector<std::pair<int, int>> queue{{int(i), j}};
		int support = 0;
		while (!queue.empty()) {
			const auto [p, q] = queue.back();
			queue.pop_back();
			support++;
			for (int d = 0; d < 4; d++) {
				const int p2 = a_.squares[size_t(p)].neighbours[size_t(d)];
				const int q2 = b_.squares[size_t(q)].neighbours[size_t(d)];
				if (p2 < 0 || q2 < 0 || match_of_a_[size_t(p2)] >= 0 || match_of_b_[size_t(q2)] >= 0 ||
				    pair_of_a.count(p2) || pair_of_b.count(q2) || a_.squares[size_t(p2)].letter < 0 ||
				    b_.squares[size_t(q2)].letter < 0 || !compatible(size_t(p2), q2, nullptr))
					continue;
				pair_of_a.emplace(p2, q2);
				pair_of_b.emplace(q2, p2);
				queue.emplace_back(p2, q2);
			}
		}
		return support;
	}

	// Every matched grid neighbour of i must be matched to j's neighbour on that side.
	bool topology_agrees(size_t i, int j) const
	{
		for (int d = 0; d < 4; d++) {
			const int ia = a_.squares[i].neighbours[size_t(d)];
			if (ia >= 0 && match_of_a_[size_t(ia)] >= 0 &&
			    match_of_a_[size_t(ia)] != b_.squares[size_t(j)].neighbours[size_t(d)])
				return false;
		}
		return true;
	}

	bool compatible(size_t i, int j, double *ret_depth) const
	{
		const Square &sa = a_.squares[i], &sb = b_.squares[size_t(j)];
		// Irregular squares (cut, bent, or two run together in a projector seam) are compared by
		// centroid only: a cut that lies on the surface (a projector's frame edge, its shadow)
		// looks the same from both cameras and so does its centroid; one that depends on the view
		// (an occluding contour) moves the centroid, and prune_matches() drops it.
		if ((sa.cell >= 0 && sb.cell >= 0 && sa.cell != sb.cell) ||
		    (sa.letter >= 0 && sb.letter >= 0 && sa.letter != sb.letter))
			return false;
		const cv::Point2d &pa = g_.na[i * kFeatureCount], &pb = g_.nb[size_t(j) * kFeatureCount];
		double z = 0;
		if (epipolar(g_, pa, pb) > check_.max_uncoded_epipolar_px || !ray_depth(g_, pa, pb, &z) ||
		    z < check_.min_depth_mm || z > check_.max_depth_mm)
			return false;
		if (ret_depth)
			*ret_depth = z;
		return true;
	}

	const CameraDetections &a_, &b_;
	const PairGeometry &g_;
	const PairCheckParams &check_;
	PairMatches &pm_;
	std::vector<int> match_of_a_, match_of_b_;
};

// Distance from p to the quadric height field z = f(x, y) fitted, over the plane of best fit, to
// `points` (a nose tip is curved within a square or two, so a plane would not do); to that plane
// when there are fewer than the 6 points a quadric needs. -1 with fewer than 3 points.
double quadric_residual(const std::vector<cv::Vec3d> &points, const cv::Vec3d &p)
{
	const int k = int(points.size());
	if (k < 3)
		return -1;
	cv::Vec3d mean(0, 0, 0);
	for (const cv::Vec3d &q : points)
		mean += q;
	mean *= 1.0 / k;
	cv::Matx33d cov = cv::Matx33d::zeros();
	for (const cv::Vec3d &q : points)
		cov += (q - mean) * (q - mean).t();
	cv::Mat values, vectors;
	cv::eigen(cv::Mat(cov), values, vectors); // descending eigenvalues: the normal is the last row
	const cv::Vec3d u(vectors.ptr<double>(0)), v(vectors.ptr<double>(1)), n(vectors.ptr<double>(2));
	if (k < 6)
		return std::fabs((p - mean).dot(n));
	cv::Mat A(k, 6, CV_64F), h(k, 1, CV_64F), c;
	for (int i = 0; i < k; i++) {
		const cv::Vec3d d = points[size_t(i)] - mean;
		const double x = d.dot(u), y = d.dot(v);
		double *row = A.ptr<double>(i);
		row[0] = x * x, row[1] = x * y, row[2] = y * y, row[3] = x, row[4] = y, row[5] = 1;
		h.at<double>(i) = d.dot(n);
	}
	if (!cv::solve(A, h, c, cv::DECOMP_SVD))
		return -1;
	const cv::Vec3d d = p - mean;
	const double x = d.dot(u), y = d.dot(v);
	const double *f = c.ptr<double>();
	return std::fabs(d.dot(n) - (f[0] * x * x + f[1] * x * y + f[2] * y * y + f[3] * x + f[4] * y + f[5]));
}

// Whether the matched squares i (camera a) and j (camera b) look cut or merged in one view: corners
// in one view only, and areas out of proportion — the area ratio b/a of i and j against the median
// ratio of i's matched grid neighbours (which carries the two views' foreshortening). Such a blob's
// area centroid need not be the slide square's centre, so its match is held to a closer fit.
bool cut_in_one_view(const CameraDetections &a, const CameraDetections &b, const std::vector<int> &partner,
		     size_t i, int j, const PruneParams &params)
{
	const Square &sa = a.squares[i], &sb = b.squares[size_t(j)];
	if (sa.has_corners == sb.has_corners)
		return false;
	std::vector<double> ratios;
	for (int n : sa.neighbours)
		if (n >= 0 && partner[size_t(n)] >= 0 && a.squares[size_t(n)].area > 0)
			ratios.push_back(b.squares[size_t(partner[size_t(n)])].area / a.squares[size_t(n)].area);
	if (ratios.empty() || sa.area <= 0)
		return true;
	std::nth_element(ratios.begin(), ratios.begin() + long(ratios.size() / 2), ratios.end());
	const double proportion = sb.area / sa.area / ratios[ratios.size() / 2];
	return proportion < params.one_sided_area_proportion[0] || proportion > params.one_sided_area_proportion[1];
}

// Removes the grown and guided squares, and the squares matched by their centroid alone (no
// corner to check them by), whose centroid lies off the surface the other matched points describe
// around it (its `surface_points` nearest, from other squares, within
// `surface_radius_mm`): a wrong candidate along the epipolar line, or a centroid shifted by a cut
// in one view. Judged after all matching, so the neighbourhood surrounds the square. Twice: a bad
// square bends its neighbours' fits. Returns how many squares it removed.
int prune_off_surface(const PairGeometry &g, const CameraDetections &a, const CameraDetections &b,
		      const PruneParams &params, PairMatches *pm)
{
	const std::vector<cv::Point2d> &na = g.na, &nb = g.nb;
	const size_t squares_a = a.squares.size();
	int removed = 0;
	for (int pass = 0; pass < 2; pass++) {
		std::vector<cv::Vec3d> pts(pm->matches.size());
		std::vector<char> ok(pm->matches.size(), 0);
		for (size_t m = 0; m < pm->matches.size(); m++) {
			const PointMatch &x = pm->matches[m];
			ok[m] = ray_point(g, na[size_t(x.square_a) * kFeatureCount + size_t(x.feature)],
					  nb[size_t(x.square_b) * kFeatureCount + size_t(x.feature)], &pts[m]);
		}
		std::vector<char> drop_square_a(squares_a, 0);
		// Squares matched by their centroid alone: no corner passed the epipolar test for them.
		std::vector<char> has_corners(squares_a, 0);
		std::vector<int> partner(squares_a, -1);
		for (const PointMatch &x : pm->matches) {
			has_corners[size_t(x.square_a)] |= x.feature != kCentroid;
			partner[size_t(x.square_a)] = x.square_b;
		}
		std::vector<std::pair<double, size_t>> nearest;
		std::vector<cv::Vec3d> hood;
		for (size_t m = 0; m < pm->matches.size(); m++) {
			const PointMatch &x = pm->matches[m];
			if (x.feature != kCentroid || !ok[m] || (!x.grown && has_corners[size_t(x.square_a)]))
				continue;
			nearest.clear();
			for (size_t o = 0; o < pm->matches.size(); o++)
				if (ok[o] && pm->matches[o].square_a != x.square_a)
					nearest.emplace_back(cv::norm(pts[o] - pts[m]), o);
			const size_t k = size_t(params.surface_points);
			// Alone (fewer than half its neighbourhood within reach): nothing vouches for it.
			hood.clear();
			if (nearest.size() >= k) {
				std::partial_sort(nearest.begin(), nearest.begin() + long(k), nearest.end());
				for (size_t i = 0; i < k && nearest[i].first <= params.surface_radius_mm; i++)
					hood.push_back(pts[nearest[i].second]);
			}
			const double limit = cut_in_one_view(a, b, partner, size_t(x.square_a), x.square_b, params)
						     ? params.max_one_sided_residual_mm
						     : params.max_surface_residual_mm;
			// Irregular (cut or bent) and far from every other matched point: grown or guided across
			// an occluding contour from the squares around it, where the quadric only extrapolates.
			const bool irregular = a.squares[size_t(x.square_a)].irregular || b.squares[size_t(x.square_b)].irregular;
			const bool isolated = nearest.empty() || nearest[0].first > params.max_irregular_isolation_mm;
			if (hood.size() < std::max<size_t>(3, k / 2) || (irregular && isolated) ||
			    quadric_residual(hood, pts[m]) > limit)
				drop_square_a[size_t(x.square_a)] = 1;
		}
		int squares = 0;
		for (char d : drop_square_a)
			squares += d;
		if (!squares)
			break;
		pm->matches.erase(std::remove_if(pm->matches.begin(), pm->matches.end(),
						 [&](const PointMatch &x) { return drop_square_a[size_t(x.square_a)] != 0; }),
				  pm->matches.end());
		removed += squares;
	}
	return removed;
}

} // namespace

Status pair_geometry(const CameraDetections &a, const CameraDetections &b, const CameraModel &ca,
		     const CameraModel &cb, PairGeometry *ret)
{
	if (ca.K(0, 0) <= 0 || cb.K(0, 0) <= 0 || ca.K(1, 1) <= 0 || cb.K(1, 1) <= 0)
		return Status::error(EINVAL, "camera intrinsics have no focal length");
	PairGeometry g;
	g.R = cb.R * ca.R.t();
	g.t = cb.T - g.R * ca.T;
	if (cv::norm(g.t) < 1e-9)
		return Status::error(EINVAL, "the two cameras share their centre");
	cv::Matx33d tx(0, -g.t[2], g.t[1], g.t[2], 0, -g.t[0], -g.t[1], g.t[0], 0);
	g.E = tx * g.R;
	g.fa = 0.5 * (ca.K(0, 0) + ca.K(1, 1));
	g.fb = 0.5 * (cb.K(0, 0) + cb.K(1, 1));
	g.na = normalised(a, ca);
	g.nb = normalised(b, cb);
	*ret = std::move(g);
	return {};
}

Status match_codes(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		   const Pattern &pattern, const PairCheckParams &check, const CodeMatchParams &params,
		   PairMatches *ret)
{
	PairMatches out;
	Status s = check_inputs("match_codes", a, b, g, &out);
	if (!s.ok())
		return s;
	const int cells = pattern.matrix.rows() * pattern.matrix.cols();
	const std::vector<cv::Point2d> &na = g.na, &nb = g.nb;

	std::unordered_map<int, std::vector<int>> by_cell;
	for (size_t j = 0; j < b.squares.size(); j++)
		if (b.squares[j].cell >= 0 && b.squares[j].cell < cells && !b.squares[j].irregular)
			by_cell[b.squares[j].cell].push_back(int(j));
	const int cols = pattern.matrix.cols();
	std::vector<int> comp_a = grid_parts(a, cols), comp_b = grid_parts(b, cols);

	// Every same-cell candidate, with its geometric verdicts (matched, and the copy vote's),
	// tallied per pair of grid parts.
	struct Cand {
		int i, j;
		bool ok;
	};
	auto corners_agree = [&](size_t i, size_t j) {
		return check.corners && a.squares[i].has_corners && b.squares[j].has_corners &&
		       corners_on_lines(g, i, j, check.max_corner_epipolar_px);
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
			const bool depth_ok = ray_depth(g, pa, pb, &z) && z >= check.min_depth_mm && z <= check.max_depth_mm;
			const double e = epipolar(g, pa, pb);
			const bool ok = depth_ok && (e <= params.max_epipolar_px || corners_agree(i, size_t(j)));
			cands.push_back({int(i), j, ok});
			auto &t = tally[{comp_a[i], comp_b[size_t(j)]}];
			t.first += ok || (depth_ok && e <= params.copy_epipolar_px);
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
	PairMatcher matcher(a, b, g, check, &out);
	for (size_t i = 0; i < a.squares.size(); i++) {
		int j = partner[i];
		if (j < 0)
			continue;
		if (taken[size_t(j)] > 1) { // two copies in a claim one square in b
			out.rejected_ambiguous++;
			continue;
		}
		if (!matcher.add_square(i, j, false))
			out.rejected_epipolar++;
	}
	*ret = std::move(out);
	return {};
}

Status grow_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		    const PairCheckParams &check, const GrowParams &params, PairMatches *matches)
{
	Status s = check_inputs("grow_matches", a, b, g, matches);
	if (!s.ok() || !params.enabled)
		return s;
	// Every square matched before has had its neighbours tried already, with fewer matches
	// around them; matches are only added, so they find nothing new and only the latest grow.
	PairMatcher matcher(a, b, g, check, matches);
	matches->grown += matcher.grow(matcher.matched());
	return {};
}

Status guide_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		     const PairCheckParams &check, const GuideParams &params, PairMatches *matches)
{
	Status s = check_inputs("guide_matches", a, b, g, matches);
	if (!s.ok() || !params.enabled)
		return s;
	PairMatcher matcher(a, b, g, check, matches);
	matches->guided += matcher.guide(params);
	return {};
}

Status seed_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		    const PairCheckParams &check, const SeedParams &params, PairMatches *matches)
{
	Status s = check_inputs("seed_matches", a, b, g, matches);
	if (!s.ok() || !params.enabled)
		return s;
	PairMatcher matcher(a, b, g, check, matches);
	int grown = 0;
	matches->seeded += matcher.seed(params, &grown);
	matches->grown += grown;
	return {};
}

Status prune_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		     const PruneParams &params, PairMatches *matches)
{
	Status s = check_inputs("prune_matches", a, b, g, matches);
	if (!s.ok())
		return s;
	matches->pruned += prune_off_surface(g, a, b, params, matches);
	return {};
}

Status match_pair(const CameraDetections &a, const CameraDetections &b, const CameraModel &ca,
		  const CameraModel &cb, const Pattern &pattern, const MatchParams &params,
		  PairMatches *ret)
{
	PairGeometry g;
	Status s = pair_geometry(a, b, ca, cb, &g);
	if (!s.ok())
		return Status::error(s.code(), "match_pair: " + s.message());
	PairMatches out;
	s = match_codes(a, b, g, pattern, params.check, params.code, &out);
	if (s.ok())
		s = grow_matches(a, b, g, params.check, params.grow, &out);
	for (int round = 0; s.ok() && round < params.guide.rounds; round++) {
		const int guided = out.guided;
		s = guide_matches(a, b, g, params.check, params.guide, &out);
		if (!s.ok() || out.guided == guided)
			break;
		s = grow_matches(a, b, g, params.check, params.grow, &out);
	}
	if (s.ok())
		s = seed_matches(a, b, g, params.check, params.seed, &out);
	if (s.ok())
		s = prune_matches(a, b, g, params.prune, &out);
	if (!s.ok())
		return s;
	*ret = std::move(out);
	return {};
}

} // namespace facescan::recon
