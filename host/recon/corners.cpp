// Stage 5: the paper's force-field corner detector, then sub-pixel refinement by edge lines.
#include "recon/image_stages.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace facescan::recon {

namespace {

using Corners = std::array<cv::Point2d, 4>;

// Bilinear sample of a CV_32F image; false outside.
bool sample(const cv::Mat &img, double x, double y, float *ret)
{
	if (!(x >= 0 && y >= 0 && x < img.cols - 1 && y < img.rows - 1))
		return false;
	int x0 = int(x), y0 = int(y);
	float fx = float(x - x0), fy = float(y - y0);
	const float *r0 = img.ptr<float>(y0), *r1 = img.ptr<float>(y0 + 1);
	*ret = (r0[x0] * (1 - fx) + r0[x0 + 1] * fx) * (1 - fy) + (r1[x0] * (1 - fx) + r1[x0 + 1] * fx) * fy;
	return true;
}

struct Line {
	cv::Point2d p, d; // a point and a unit direction
	double rms = 0;
};

// Total least squares with one round of outlier rejection.
bool fit_line(std::vector<cv::Point2d> pts, Line *ret)
{
	for (int round = 0; round < 2; round++) {
		if (pts.size() < 3)
			return false;
		cv::Point2d m(0, 0);
		for (const auto &p : pts)
			m += p;
		m *= 1.0 / double(pts.size());
		double sxx = 0, sxy = 0, syy = 0;
		for (const auto &p : pts) {
			cv::Point2d q = p - m;
			sxx += q.x * q.x;
			sxy += q.x * q.y;
			syy += q.y * q.y;
		}
		double ang = 0.5 * std::atan2(2 * sxy, sxx - syy);
		cv::Point2d d(std::cos(ang), std::sin(ang));
		cv::Point2d n(-d.y, d.x);
		double ss = 0;
		std::vector<double> res(pts.size());
		for (size_t k = 0; k < pts.size(); k++) {
			res[k] = (pts[k] - m).dot(n);
			ss += res[k] * res[k];
		}
		double rms = std::sqrt(ss / double(pts.size()));
		*ret = {m, d, rms};
		if (round == 1)
			break;
		double cut = std::max(2.5 * rms, 0.3);
		std::vector<cv::Point2d> keep;
		for (size_t k = 0; k < pts.size(); k++)
			if (std::abs(res[k]) <= cut)
				keep.push_back(pts[k]);
		if (keep.size() == pts.size())
			break;
		pts.swap(keep);
	}
	return true;
}

bool intersect(const Line &a, const Line &b, cv::Point2d *ret)
{
	double den = a.d.x * b.d.y - a.d.y * b.d.x;
	if (std::abs(den) < 0.2) // less than ~11.5°: no well-defined corner
		return false;
	cv::Point2d w = b.p - a.p;
	double t = (w.x * b.d.y - w.y * b.d.x) / den;
	*ret = a.p + t * a.d;
	return true;
}

// The edge of one side of the square, located at the midpoint level along profiles across it.
bool side_points(const cv::Mat &img, const cv::Point2d &from, const cv::Point2d &to,
		 const cv::Point2d &centre, double side, double min_step, const CornerParams &params,
		 std::vector<cv::Point2d> *ret)
{
	cv::Point2d dir = to - from;
	double len = std::hypot(dir.x, dir.y);
	if (len < 2)
		return false;
	dir *= 1.0 / len;
	cv::Point2d n(-dir.y, dir.x);
	if ((0.5 * (from + to) - centre).dot(n) < 0)
		n = -n;
	double lin = std::min(params.profile_half_px, 0.3 * side);
	double lout = std::min(params.profile_half_px, 0.35 * side);
	const double step = 0.5;
	int kin = int(std::ceil(lin / step)), kout = int(std::ceil(lout / step));
	int count = std::clamp(int(std::lround(len)), params.samples_per_side, 48);
	std::vector<float> v(size_t(kin + kout + 1));
	ret->clear();
	for (int s = 0; s < count; s++) {
		double t = params.side_margin + (1 - 2 * params.side_margin) * (s + 0.5) / count;
		cv::Point2d base = from + t * len * dir;
		bool ok = true;
		for (int k = -kin; k <= kout && ok; k++) {
			cv::Point2d q = base + (k * step) * n;
			ok = sample(img, q.x, q.y, &v[size_t(k + kin)]);
		}
		if (!ok)
			continue;
		float hi = *std::max_element(v.begin(), v.begin() + kin + 1);
		float lo = *std::min_element(v.begin() + kin, v.end());
		if (hi - lo < min_step)
			continue;
		float mid = 0.5f * (hi + lo);
		double best = 1e9;
		for (size_t k = 1; k < v.size(); k++)
			if (v[k - 1] >= mid && v[k] < mid) {
				double off = (double(k) - 1 + (v[k - 1] - mid) / (v[k - 1] - v[k])) * step -
					     kin * step;
				if (std::abs(off) < std::abs(best))
					best = off;
			}
		if (best < 1e8)
			ret->push_back(base + best * n);
	}
	return ret->size() >= 4;
}

bool convex_quad(const Corners &c)
{
	int sign = 0;
	for (int k = 0; k < 4; k++) {
		cv::Point2d a = c[size_t((k + 1) % 4)] - c[size_t(k)];
		cv::Point2d b = c[size_t((k + 2) % 4)] - c[size_t((k + 1) % 4)];
		double z = a.x * b.y - a.y * b.x;
		int s = z > 0 ? 1 : (z < 0 ? -1 : 0);
		if (!s || (sign && s != sign))
			return false;
		sign = s;
	}
	return true;
}

} // namespace

Status force_field_corners(const cv::Mat &mask, std::array<cv::Point2d, 4> *ret_corners)
{
	if (mask.empty() || mask.type() != CV_8U)
		return Status::error(EINVAL, "force-field corners need a CV_8U mask");
	const int w = mask.cols, h = mask.rows;
	// Boundary pixels: inside, with a 4-neighbour outside (or the mask's edge).
	cv::Mat edge(h, w, CV_8U, cv::Scalar(0));
	int x0 = w, x1 = -1, y0 = h, y1 = -1;
	for (int y = 0; y < h; y++) {
		const uchar *m = mask.ptr<uchar>(y);
		const uchar *up = y > 0 ? mask.ptr<uchar>(y - 1) : nullptr;
		const uchar *dn = y < h - 1 ? mask.ptr<uchar>(y + 1) : nullptr;
		uchar *e = edge.ptr<uchar>(y);
		for (int x = 0; x < w; x++) {
			if (!m[x])
				continue;
			x0 = std::min(x0, x), x1 = std::max(x1, x);
			y0 = std::min(y0, y), y1 = std::max(y1, y);
			bool b = !up || !up[x] || !dn || !dn[x] || x == 0 || !m[x - 1] || x == w - 1 ||
				 !m[x + 1];
			e[x] = b;
		}
	}
	if (x1 < 0)
		return Status::error(EINVAL, "force-field corners: empty mask");
	// F_h and F_v: the length of the horizontal / vertical run of boundary pixels through a pixel.
	cv::Mat fh(h, w, CV_32S, cv::Scalar(0)), fv(h, w, CV_32S, cv::Scalar(0));
	for (int y = 0; y < h; y++) {
		const uchar *e = edge.ptr<uchar>(y);
		int *f = fh.ptr<int>(y);
		for (int x = 0; x < w;) {
			if (!e[x]) {
				x++;
				continue;
			}
			int s = x;
			while (x < w && e[x])
				x++;
			for (int k = s; k < x; k++)
				f[k] = x - s;
		}
	}
	for (int x = 0; x < w; x++)
		for (int y = 0; y < h;) {
			if (!edge.at<uchar>(y, x)) {
				y++;
				continue;
			}
			int s = y;
			while (y < h && edge.at<uchar>(y, x))
				y++;
			for (int k = s; k < y; k++)
				fv.at<int>(k, x) = y - s;
		}
	// The bounding box in four quadrants; per quadrant the F_total maximum, ties averaged.
	double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
	std::array<int, 4> best{{-1, -1, -1, -1}};
	std::array<cv::Point2d, 4> sum{};
	std::array<int, 4> n{};
	for (int y = y0; y <= y1; y++) {
		const uchar *e = edge.ptr<uchar>(y);
		for (int x = x0; x <= x1; x++) {
			if (!e[x])
				continue;
			int total = fh.at<int>(y, x) + fv.at<int>(y, x);
			bool left = x <= xm, right = x >= xm, top = y <= ym, bottom = y >= ym;
			for (int q = 0; q < 4; q++) {
				bool in = (q == 0 && top && left) || (q == 1 && top && right) ||
					  (q == 2 && bottom && right) || (q == 3 && bottom && left);
				if (!in)
					continue;
				size_t k = size_t(q);
				if (total > best[k]) {
					best[k] = total;
					sum[k] = cv::Point2d(x, y);
					n[k] = 1;
				} else if (total == best[k]) {
					sum[k] += cv::Point2d(x, y);
					n[k]++;
				}
			}
		}
	}
	for (size_t k = 0; k < 4; k++)
		if (!n[k])
			return Status::error(EINVAL, "force-field corners: a quadrant has no boundary");
	// The boundary pixels are the square's outermost pixel centres; its outline lies half a pixel
	// further out, so corners move half a pixel away from the box centre.
	std::array<cv::Point2d, 4> out;
	const double dx[4] = {-0.5, 0.5, 0.5, -0.5}, dy[4] = {-0.5, -0.5, 0.5, 0.5};
	for (size_t k = 0; k < 4; k++)
		out[k] = sum[k] * (1.0 / n[k]) + cv::Point2d(dx[k], dy[k]);
	*ret_corners = out;
	return {};
}

namespace {

// Pixel-level sides from the mask's boundary: each boundary pixel whose intensity gradient points
// along a side's normal (as the initial corners give it) belongs to that side. The gradient, not
// the position, decides, so initial corners a few pixels off (the force field's tie averaging on a
// slightly rotated square) still give the right sides.
bool boundary_corners(const cv::Mat &intensity, const SquareBlob &blob, Corners *c)
{
	const cv::Mat &m = blob.mask;
	cv::Point2d centre = 0.25 * ((*c)[0] + (*c)[1] + (*c)[2] + (*c)[3]);
	std::array<cv::Point2d, 4> normal;
	for (size_t k = 0; k < 4; k++) {
		cv::Point2d d = (*c)[(k + 1) % 4] - (*c)[k];
		cv::Point2d n(d.y, -d.x);
		double l = std::hypot(n.x, n.y);
		if (l < 1e-9)
			return false;
		n *= 1.0 / l;
		if ((0.5 * ((*c)[k] + (*c)[(k + 1) % 4]) - centre).dot(n) < 0)
			n = -n;
		normal[k] = n;
	}
	std::array<std::vector<cv::Point2d>, 4> pts;
	const double cos_limit = std::cos(35.0 * M_PI / 180.0);
	for (int y = 0; y < m.rows; y++)
		for (int x = 0; x < m.cols; x++) {
			if (!m.at<uchar>(y, x))
				continue;
			bool edge = y == 0 || x == 0 || y == m.rows - 1 || x == m.cols - 1 ||
				    !m.at<uchar>(y - 1, x) || !m.at<uchar>(y + 1, x) || !m.at<uchar>(y, x - 1) ||
				    !m.at<uchar>(y, x + 1);
			if (!edge)
				continue;
			int ix = blob.box.x + x, iy = blob.box.y + y;
			if (ix < 1 || iy < 1 || ix >= intensity.cols - 1 || iy >= intensity.rows - 1)
				continue;
			// Outward normal = minus the gradient (bright inside).
			double gx = -(intensity.at<float>(iy, ix + 1) - intensity.at<float>(iy, ix - 1));
			double gy = -(intensity.at<float>(iy + 1, ix) - intensity.at<float>(iy - 1, ix));
			double g = std::hypot(gx, gy);
			if (g < 1e-6)
				continue;
			for (size_t k = 0; k < 4; k++)
				if ((gx * normal[k].x + gy * normal[k].y) / g > cos_limit) {
					// The outline lies half a pixel outside the boundary pixel's centre.
					pts[k].push_back(cv::Point2d(ix, iy) + 0.5 * normal[k]);
					break;
				}
		}
	std::array<Line, 4> lines;
	for (size_t k = 0; k < 4; k++)
		if (!fit_line(pts[k], &lines[k]))
			return false;
	Corners next;
	for (size_t k = 0; k < 4; k++)
		if (!intersect(lines[(k + 3) % 4], lines[k], &next[k]))
			return false;
	*c = next;
	return true;
}

} // namespace

Status refine_corners(const cv::Mat &intensity, const SquareBlob &blob, const CornerParams &params,
		      std::array<cv::Point2d, 4> *corners)
{
	if (intensity.empty() || intensity.type() != CV_32F)
		return Status::error(EINVAL, "refine_corners needs a CV_32F intensity image");
	Corners c = *corners;
	double side = std::sqrt(std::max(1.0, double(cv::countNonZero(blob.mask))));
	if (!boundary_corners(intensity, blob, &c) || !convex_quad(c)) {
		// The force field's quadrants fail on squares turned near 45° or strongly sheared;
		// start again from the minimum-area rectangle around the mask.
		std::vector<cv::Point> nz;
		cv::findNonZero(blob.mask, nz);
		if (nz.size() < 4)
			return Status::error(ERANGE, "the square is too small");
		cv::Point2f box[4];
		cv::minAreaRect(nz).points(box);
		cv::Point2d ctr(0, 0);
		for (const auto &b : box)
			ctr += cv::Point2d(b);
		ctr *= 0.25;
		std::array<std::pair<double, cv::Point2d>, 4> by_angle;
		for (size_t k = 0; k < 4; k++) {
			cv::Point2d q(box[k]);
			by_angle[k] = {std::atan2(q.y - ctr.y, q.x - ctr.x), q + cv::Point2d(blob.box.x, blob.box.y)};
		}
		// Ascending angle from -180°, image y down: TL, TR, BR, BL for an upright square.
		std::sort(by_angle.begin(), by_angle.end(),
			  [](const auto &a, const auto &b) { return a.first < b.first; });
		for (size_t k = 0; k < 4; k++)
			c[k] = by_angle[k].second;
		if (!boundary_corners(intensity, blob, &c))
			return Status::error(ERANGE, "the square's boundary has no four sides");
	}
	const Corners pixel_level = c;
	double min_step = 0.3 * std::max(1.0, blob.inside - blob.outside);
	std::vector<cv::Point2d> pts;
	for (int iter = 0; iter < 2; iter++) {
		cv::Point2d centre = 0.25 * (c[0] + c[1] + c[2] + c[3]);
		std::array<Line, 4> lines;
		for (size_t k = 0; k < 4; k++) {
			if (!side_points(intensity, c[k], c[(k + 1) % 4], centre, side, min_step, params,
					 &pts) ||
			    !fit_line(pts, &lines[k]))
				return Status::error(ERANGE, "too few edge points on a side");
			if (lines[k].rms > params.max_fit_rms_px)
				return Status::error(ERANGE, "edge points do not fit a line");
		}
		Corners next;
		for (size_t k = 0; k < 4; k++)
			if (!intersect(lines[(k + 3) % 4], lines[k], &next[k]))
				return Status::error(ERANGE, "adjacent sides are nearly parallel");
		c = next;
	}
	// The mask's outline (one threshold per square) bends where the skin's albedo changes within
	// the square (brows, lips); the edge profiles (one level per profile) do not.
	double limit = std::max(params.max_shift_px, 0.2 * side);
	for (size_t k = 0; k < 4; k++)
		if (cv::norm(c[k] - pixel_level[k]) > limit)
			return Status::error(ERANGE, "refined corner moved too far");
	if (!convex_quad(c))
		return Status::error(ERANGE, "refined corners are not a convex quadrilateral");
	*corners = c;
	return {};
}

void detect_corners(const cv::Mat &intensity, const std::vector<SquareBlob> &blobs,
		    const CornerParams &params, std::vector<Square> *squares)
{
	for (size_t i = 0; i < blobs.size() && i < squares->size(); i++) {
		Square &sq = (*squares)[i];
		const SquareBlob &b = blobs[i];
		sq.has_corners = false;
		Corners c;
		if (!force_field_corners(b.mask, &c).ok())
			continue;
		for (auto &p : c)
			p += cv::Point2d(b.box.x, b.box.y);
		if (params.subpixel && !refine_corners(intensity, b, params, &c).ok())
			continue;
		if (!convex_quad(c))
			continue;
		sq.corners = c;
		sq.has_corners = true;
		// The diagonals' intersection: a projective invariant, the same surface point in every view.
		cv::Point2d d1 = c[2] - c[0], d2 = c[3] - c[1], w = c[1] - c[0];
		double den = d1.x * d2.y - d1.y * d2.x;
		if (std::abs(den) > 1e-9) {
			double t = (w.x * d2.y - w.y * d2.x) / den;
			sq.centroid = c[0] + t * d1;
		}
	}
}

} // namespace facescan::recon
