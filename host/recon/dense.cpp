// Stage D: dense matching of one pair, seeded and bounded by the code. See dense.hpp.
#include "recon/dense.hpp"

#include "recon/meshing.hpp"
#include "recon/triangulate.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <Eigen/Dense>

namespace facescan::recon {

namespace {

cv::Matx33d rectified_K(const RectifiedPair &rp, int which)
{
	return cv::Matx33d(rp.f, 0, which == 0 ? rp.cx1 : rp.cx2, 0, rp.f, rp.cy, 0, 0, 1);
}

double median(std::vector<double> v)
{
	if (v.empty())
		return 0;
	std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
	return v[v.size() / 2];
}

// Fills the triangle (pixel centres inside it) of `prior` with the linear interpolation of the
// vertex disparities.
void fill_triangle(cv::Mat *prior, const cv::Point2d p[3], const double d[3])
{
	const double x0 = std::min({p[0].x, p[1].x, p[2].x}), x1 = std::max({p[0].x, p[1].x, p[2].x});
	const double y0 = std::min({p[0].y, p[1].y, p[2].y}), y1 = std::max({p[0].y, p[1].y, p[2].y});
	const int c0 = std::max(0, int(std::ceil(x0))), c1 = std::min(prior->cols - 1, int(std::floor(x1)));
	const int r0 = std::max(0, int(std::ceil(y0))), r1 = std::min(prior->rows - 1, int(std::floor(y1)));
	const double den = (p[1].y - p[2].y) * (p[0].x - p[2].x) + (p[2].x - p[1].x) * (p[0].y - p[2].y);
	if (std::fabs(den) < 1e-9)
		return;
	for (int y = r0; y <= r1; ++y) {
		float *row = prior->ptr<float>(y);
		for (int x = c0; x <= c1; ++x) {
			const double l0 = ((p[1].y - p[2].y) * (x - p[2].x) + (p[2].x - p[1].x) * (y - p[2].y)) / den;
			const double l1 = ((p[2].y - p[0].y) * (x - p[2].x) + (p[0].x - p[2].x) * (y - p[2].y)) / den;
			const double l2 = 1 - l0 - l1;
			if (l0 < -1e-9 || l1 < -1e-9 || l2 < -1e-9)
				continue;
			row[x] = float(l0 * d[0] + l1 * d[1] + l2 * d[2]);
		}
	}
}

// Zero-mean normalised cross-correlation of a and b over `block`-sized windows (CV_32F, -1..1),
// and the standard deviation of a over the same windows.
void window_ncc(const cv::Mat &a, const cv::Mat &b, int block, cv::Mat *ret_ncc, cv::Mat *ret_std_a)
{
	const cv::Size k(block, block);
	cv::Mat ma, mb, maa, mbb, mab;
	cv::boxFilter(a, ma, CV_32F, k);
	cv::boxFilter(b, mb, CV_32F, k);
	cv::boxFilter(a.mul(a), maa, CV_32F, k);
	cv::boxFilter(b.mul(b), mbb, CV_32F, k);
	cv::boxFilter(a.mul(b), mab, CV_32F, k);
	cv::Mat va = maa - ma.mul(ma), vb = mbb - mb.mul(mb), cov = mab - ma.mul(mb);
	cv::max(va, 1e-6, va);
	cv::max(vb, 1e-6, vb);
	cv::Mat den;
	cv::sqrt(va.mul(vb), den);
	*ret_ncc = cov / den;
	cv::sqrt(va, *ret_std_a);
}

// World points into the pair's rectified views: each camera's rotation composed with its
// rectification once, for the many points of a guide.
struct RectifiedProjection {
	RectifiedProjection(const RectifiedPair &rp, const CameraModel &a, const CameraModel &b)
		: rp(rp), Ra(rp.R1 * a.R), Rb(rp.R2 * b.R), Ta(rp.R1 * a.T), Tb(rp.R2 * b.T)
	{
	}
	// The left view's x, y and the disparity x_a - x_b of world point w; false when it is not in
	// front of both cameras.
	bool operator()(const cv::Vec3d &w, cv::Point3d *ret) const
	{
		const cv::Vec3d qa = Ra * w + Ta, qb = Rb * w + Tb;
		if (!(qa[2] > 1e-6 && qb[2] > 1e-6))
			return false;
		const double x = rp.f * qa[0] / qa[2] + rp.cx1;
		*ret = cv::Point3d(x, rp.f * qa[1] / qa[2] + rp.cy, x - (rp.f * qb[0] / qb[2] + rp.cx2));
		return true;
	}
	const RectifiedPair &rp;
	cv::Matx33d Ra, Rb;
	cv::Vec3d Ta, Tb;
};

// Disparities (rectified pixels) a point can have in the pair when it lies within `depth_mm`
// of where the two optical axes pass closest, and within ±`side_mm` across them.
void volume_disparity_range(const RectifiedPair &rp, const CameraModel &a, const CameraModel &b, double depth_mm,
			    double side_mm, double *ret_lo, double *ret_hi)
{
	const cv::Vec3d centre = axes_meet(a, b);
	const cv::Vec3d da = a.R.t() * cv::Vec3d(0, 0, 1), db = b.R.t() * cv::Vec3d(0, 0, 1);
	cv::Vec3d axis = da + db;
	axis *= 1.0 / std::max(1e-9, cv::norm(axis));
	cv::Vec3d side = axis.cross(a.R.t() * cv::Vec3d(0, 1, 0));
	side *= 1.0 / std::max(1e-9, cv::norm(side));
	const cv::Vec3d up = side.cross(axis);
	const RectifiedProjection project(rp, a, b);
	double lo = 1e9, hi = -1e9;
	for (int k = 0; k < 27; ++k) {
		const cv::Vec3d p = centre + axis * ((k % 3 - 1) * depth_mm) + side * ((k / 3 % 3 - 1) * side_mm) +
				    up * ((k / 9 - 1) * side_mm);
		cv::Point3d q;
		if (!project(p, &q))
			continue;
		lo = std::min(lo, q.z);
		hi = std::max(hi, q.z);
	}
	*ret_lo = lo;
	*ret_hi = hi;
}

// The coarse stage: SGBM over a whole disparity range at half the matching resolution, for the
// parts of the face no code point reaches (CV_32F at the matching resolution, NaN = none), on the
// columns and rows of `need` (matching resolution) only. The images are cut to them (plus a
// margin, so that SGBM's paths start outside them) and, to the left, by the largest disparity,
// so that every match of a needed pixel stays inside the cut: the cut changes no disparity's
// meaning, it only skips what the lit test would drop anyway.
cv::Mat coarse_disparity(const cv::Mat &left, const cv::Mat &right, double lo, double hi, cv::Rect need,
			 const DenseParams &params)
{
	const float nan = std::numeric_limits<float>::quiet_NaN();
	cv::Mat out(left.size(), CV_32F, cv::Scalar(nan));
	const cv::Rect frame(cv::Point(0, 0), left.size());
	need &= frame;
	if (need.empty())
		return out;
	const int mind = int(std::floor(lo / 2)) - 2;
	const int block = params.block;
	// The range as over the whole width (capped at half of it; SGBM needs its whole range
	// inside the image, OpenCV asserts deep inside otherwise).
	const int cols2 = (left.cols + 1) / 2;
	int nd = int(std::ceil((hi - lo) / 2)) + 4;
	nd = std::min(((nd + 15) / 16) * 16, std::max(16, (cols2 / 2 / 16) * 16));
	if (mind + nd > cols2 - block - 1)
		nd = ((cols2 - block - 1 - mind) / 16) * 16;
	if (nd < 16 || mind < -cols2)
		return out;
	const int margin = 2 * params.coarse_margin_px;
	const int reach_left = 2 * std::max(0, mind + nd), reach_right = 2 * std::max(0, -mind);
	// Even corners: the half-resolution pixel x of the cut is pixel 2x of the matching one.
	int x0 = std::max(0, need.x - margin - reach_left) & ~1, x1 = std::min(left.cols, need.br().x + margin + reach_right);
	const int y0 = std::max(0, need.y - margin) & ~1, y1 = std::min(left.rows, need.br().y + margin);
	// A cut too narrow for the range (a frame edge) searches the whole width instead of less range.
	if (mind + nd > (x1 - x0) / 2 - block - 1) {
		x0 = 0;
		x1 = left.cols;
	}
	const cv::Rect cut(x0, y0, x1 - x0, y1 - y0);
	cv::Mat l2, r2;
	cv::pyrDown(left(cut), l2);
	cv::pyrDown(right(cut), r2);
	cv::Ptr<cv::StereoSGBM> sgbm =
		cv::StereoSGBM::create(mind, nd, block, params.p1_factor * l2.channels() * block * block,
				       params.p2_factor * l2.channels() * block * block, 1, 31, 10,
				       params.speckle_window / 4, 1, cv::StereoSGBM::MODE_SGBM_3WAY);
	cv::Mat d16;
	sgbm->compute(l2, r2, d16);
	cv::Mat coarse(l2.size(), CV_32F);
	for (int y = 0; y < l2.rows; ++y) {
		const short *dr = d16.ptr<short>(y);
		float *cr = coarse.ptr<float>(y);
		for (int x = 0; x < l2.cols; ++x)
			cr[x] = dr[x] >= mind * 16 ? 2.f * dr[x] / 16.f : nan;
	}
	cv::resize(coarse, out(cut), cut.size(), 0, 0, cv::INTER_NEAREST);
	return out;
}

// Where the pattern falls: its squares and gaps give every window about one pitch wide a
// contrast that unlit skin, hair and the booth's walls (sensor noise only) do not have.
cv::Mat pattern_lit(const cv::Mat &grey32, double pitch, const DenseParams &params)
{
	cv::Mat mean, sq;
	const int win = std::max(5, int(std::lround(params.contrast_window_pitches * pitch)) | 1);
	cv::boxFilter(grey32, mean, CV_32F, cv::Size(win, win));
	cv::boxFilter(grey32.mul(grey32), sq, CV_32F, cv::Size(win, win));
	const cv::Mat var = sq - mean.mul(mean);
	const float min_var = float(params.min_pattern_contrast * params.min_pattern_contrast);
	cv::Mat lit(grey32.size(), CV_8U);
	for (int y = 0; y < lit.rows; ++y) {
		const float *vr = var.ptr<float>(y);
		uchar *lr = lit.ptr<uchar>(y);
		for (int x = 0; x < lit.cols; ++x)
			lr[x] = vr[x] < min_var ? 0 : 255;
	}
	return lit;
}

// The disparity the guide's points give the pair: each point projected into both rectified views.
// A point more than `guide_hidden_px` of disparity behind the nearest point in its cell of the
// right view is hidden from the right camera, and left out; of the others, per cell of the left
// view the nearest (where points of the far side of the head fall among those of the near side,
// the left camera sees the near side). The cells' points are interpolated over triangles at most
// `guide_edge_factor` cells long, so no triangle spans a hole or an outline.
cv::Mat guide_disparity(const RectifiedPair &rp, const CameraModel &a, const CameraModel &b,
			const std::vector<cv::Point3f> &points, const DenseParams &params)
{
	const int cell = std::max(1, params.guide_cell_px);
	const int cols = (rp.size.width + cell - 1) / cell, rows = (rp.size.height + cell - 1) / cell;
	const auto cell_of = [&](double x, double y) { return size_t(int(y) / cell * cols + int(x) / cell); };
	const auto inside = [&](double x) { return x >= 0 && x < rp.size.width; };
	const double none = -std::numeric_limits<double>::infinity();
	std::vector<double> nearest_right(size_t(cols * rows), none);
	std::vector<cv::Point3d> projected; // left x, y, disparity
	projected.reserve(points.size());
	const RectifiedProjection project(rp, a, b);
	for (const cv::Point3f &p : points) {
		cv::Point3d q;
		if (!project(cv::Vec3d(p.x, p.y, p.z), &q) || !(inside(q.x) && q.y >= 0 && q.y < rp.size.height))
			continue;
		projected.push_back(q);
		if (inside(q.x - q.z)) {
			double &n = nearest_right[cell_of(q.x - q.z, q.y)];
			n = std::max(n, q.z);
		}
	}
	std::vector<cv::Point2d> best_at(size_t(cols * rows));
	std::vector<double> best_d(size_t(cols * rows), none);
	for (const cv::Point3d &q : projected) {
		if (inside(q.x - q.z) && q.z < nearest_right[cell_of(q.x - q.z, q.y)] - params.guide_hidden_px)
			continue;
		const size_t k = cell_of(q.x, q.y);
		if (q.z > best_d[k]) {
			best_d[k] = q.z;
			best_at[k] = cv::Point2d(q.x, q.y);
		}
	}
	std::vector<cv::Point2d> seeds;
	std::vector<double> seed_d;
	for (size_t k = 0; k < best_d.size(); ++k)
		if (std::isfinite(best_d[k])) {
			seeds.push_back(best_at[k]);
			seed_d.push_back(best_d[k]);
		}
	return disparity_prior(rp.size, seeds, seed_d, params.guide_edge_factor, 0, nullptr);
}

} // namespace

// The code's own prior, which every match of the pair starts from, from its seeds and rectified
// left view: its piecewise-linear disparity where its triangles are small (`tight`) and over the
// long ones too (`loose`), where the pattern falls (`pattern_lit`), and the bounding box of the
// lit pixels the small triangles miss.
static void code_prior(PreparedPair *pp)
{
	const DenseParams &params = pp->params;
	const cv::Size size = pp->rp.size;
	const bool coded = int(pp->seeds.size()) >= params.min_seeds;
	pp->tight = coded ? disparity_prior(size, pp->seeds, pp->seed_d, params.tight_edge_factor,
					    params.extrapolate_spacings, &pp->median_spacing_px)
			  : cv::Mat(size, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
	const double pitch = pp->median_spacing_px > 0 ? 2 * pp->median_spacing_px : params.default_pitch_px;
	pp->lit = pattern_lit(pp->grey_l32, pitch, params);
	pp->loose = coded ? disparity_prior(size, pp->seeds, pp->seed_d, params.max_seed_edge_factor,
					    params.extrapolate_spacings, nullptr)
			  : pp->tight.clone();
	const cv::Mat uncovered = pp->lit & ~has_value(pp->tight);
	pp->uncovered = cv::boundingRect(uncovered);
	const int lit_px = cv::countNonZero(pp->lit);
	pp->seed_cover = coded && lit_px > 0 ? 1 - double(cv::countNonZero(uncovered)) / lit_px : 0;
}

// One match's prior: the code's small triangles; where they give none, the guide's points (the
// guided pass); where neither does, the coarse search (its range is the seeds' disparities plus
// a margin, so it cannot reach another copy of the slide); the long triangles that bridge such
// holes where the coarse search found nothing. Only lit pixels keep a prior, so the coarse
// search runs on them only.
static cv::Mat match_prior(const PreparedPair &pp, const std::vector<cv::Point3f> *guide, DenseStats *stats)
{
	const DenseParams &params = pp.params;
	const bool coded = int(pp.seeds.size()) >= params.min_seeds;
	cv::Mat tight = pp.tight.clone();
	cv::Rect need = pp.uncovered;
	// The guided pass: the dense points fill what the code's small triangles miss, before the
	// coarse search, which keeps only what neither reaches.
	if (guide && !guide->empty()) {
		const cv::Mat guided = guide_disparity(pp.rp, pp.a, pp.b, *guide, params);
		for (int y = 0; y < tight.rows; ++y) {
			float *tr = tight.ptr<float>(y);
			const float *gr = guided.ptr<float>(y);
			for (int x = 0; x < tight.cols; ++x)
				if (tr[x] != tr[x] && gr[x] == gr[x]) {
					tr[x] = gr[x];
					stats->guided_pixels++;
				}
		}
		need = cv::boundingRect(pp.lit & ~has_value(tight));
	}
	if (!params.coarse)
		return coded ? pp.loose.clone() : tight;
	if (need.empty())
		return tight;
	// The seeds' range, widened to the working volume's when they are none or in one corner.
	double lo = std::numeric_limits<double>::infinity(), hi = -lo;
	if (coded) {
		lo = *std::min_element(pp.seed_d.begin(), pp.seed_d.end());
		hi = *std::max_element(pp.seed_d.begin(), pp.seed_d.end());
		const double margin = 0.15 * (hi - lo) + 2 * params.residual_px;
		lo -= margin;
		hi += margin;
	}
	if (!coded || pp.seed_cover < params.min_seed_cover) {
		double vlo, vhi;
		volume_disparity_range(pp.rp, pp.a, pp.b, params.volume_depth_mm, params.volume_side_mm, &vlo, &vhi);
		if (vhi > vlo) {
			lo = std::min(lo, vlo);
			hi = std::max(hi, vhi);
			stats->coarse_over_volume = true;
		}
	}
	if (!(hi > lo))
		return tight;
	cv::Mat right;
	cv::remap(pp.frame_b, right, pp.rp.map2x, pp.rp.map2y, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
	const cv::Mat coarse = coarse_disparity(pp.left, right, lo, hi, need, params);
	cv::Mat prior = tight;
	for (int y = 0; y < prior.rows; ++y) {
		float *pr = prior.ptr<float>(y);
		const float *cr = coarse.ptr<float>(y), *lr = pp.loose.ptr<float>(y);
		for (int x = 0; x < prior.cols; ++x) {
			if (pr[x] == pr[x])
				continue;
			if (cr[x] == cr[x]) {
				pr[x] = cr[x];
				stats->coarse_pixels++;
			} else {
				pr[x] = lr[x]; // NaN where the long triangles do not reach either
			}
		}
	}
	return prior;
}

cv::Mat erode_outline(const cv::Mat &mask, int pinhole_px, int iterations, int shape)
{
	cv::Mat whole = mask.clone(), labels, hole_stats, centroids;
	cv::connectedComponentsWithStats(~mask, labels, hole_stats, centroids, 4, CV_32S);
	for (int y = 0; y < mask.rows; ++y) {
		const int *lr = labels.ptr<int>(y);
		uchar *wr = whole.ptr<uchar>(y);
		for (int x = 0; x < mask.cols; ++x)
			if (lr[x] > 0 && hole_stats.at<int>(lr[x], cv::CC_STAT_AREA) <= pinhole_px)
				wr[x] = 255;
	}
	cv::Mat eroded;
	cv::erode(whole, eroded, cv::getStructuringElement(shape, cv::Size(3, 3)), cv::Point(-1, -1), iterations);
	return eroded & mask;
}

cv::Mat steep_pixels(const cv::Mat &valid, const cv::Mat &disparity, const DenseParams &params)
{
	cv::Mat bad(valid.size(), CV_8U, cv::Scalar(0));
	const float g = float(params.max_disparity_gradient), fall = float(params.max_falling_gradient);
	for (int y = 1; y + 1 < valid.rows; ++y) {
		const uchar *vu = valid.ptr<uchar>(y - 1), *vr = valid.ptr<uchar>(y), *vd = valid.ptr<uchar>(y + 1);
		const float *tu = disparity.ptr<float>(y - 1), *tr = disparity.ptr<float>(y),
			    *td = disparity.ptr<float>(y + 1);
		uchar *br = bad.ptr<uchar>(y);
		for (int x = 1; x + 1 < valid.cols; ++x) {
			if (!vr[x])
				continue;
			const float along = tr[x + 1] - tr[x - 1];
			if ((vr[x - 1] && vr[x + 1] && (along > 2 * g || along < -2 * fall)) ||
			    (vu[x] && vd[x] && std::fabs(td[x] - tu[x]) > 2 * g))
				br[x] = 255;
		}
	}
	return bad;
}

RefineViews refine_views(const cv::Mat &frame_a, const cv::Mat &frame_b, const CameraModel &a, const CameraModel &b,
			 const RectifiedPair &rp, double scale, cv::Rect region)
{
	RefineViews v;
	region &= cv::Rect(cv::Point(0, 0), rp.size);
	if (region.empty() || !(scale > 0))
		return v;
	v.region = region;
	v.scale = scale;
	// Rectified again at `scale` times the matching resolution, with the same geometry scaled, so
	// that refinement x = scale * matching x; the left view over `region`, the right one over its
	// rows and the whole width: a match reads it wherever its disparity lands.
	const double k = scale;
	const double ox = region.x * k, oy = region.y * k;
	const cv::Size size_l(int(std::lround(region.width * k)), int(std::lround(region.height * k)));
	const cv::Size size_r(int(std::lround(rp.size.width * k)), size_l.height);
	const cv::Matx33d Ka(rp.f * k, 0, rp.cx1 * k - ox, 0, rp.f * k, rp.cy * k - oy, 0, 0, 1);
	const cv::Matx33d Kb(rp.f * k, 0, rp.cx2 * k, 0, rp.f * k, rp.cy * k - oy, 0, 0, 1);
	cv::Mat m1x, m1y, m2x, m2y, ga, gb;
	cv::initUndistortRectifyMap(cv::Mat(a.K), cv::Mat(a.dist), cv::Mat(rp.R1), cv::Mat(Ka), size_l, CV_32FC1, m1x,
				    m1y);
	cv::initUndistortRectifyMap(cv::Mat(b.K), cv::Mat(b.dist), cv::Mat(rp.R2), cv::Mat(Kb), size_r, CV_32FC1, m2x,
				    m2y);
	cv::cvtColor(frame_a, ga, cv::COLOR_BGR2GRAY);
	cv::cvtColor(frame_b, gb, cv::COLOR_BGR2GRAY);
	cv::remap(ga, v.left, m1x, m1y, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
	cv::remap(gb, v.right, m2x, m2y, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
	return v;
}

void refine_subpixel(const RefineViews &views, const cv::Mat &valid, const DenseParams &params, cv::Mat *disparity,
		     RefinedDisparity *ret_refined)
{
	if (ret_refined)
		*ret_refined = RefinedDisparity();
	// Only the bounding box of the valid pixels is refined (the face is a fraction of the frame).
	if (views.left.empty())
		return;
	const cv::Rect roi = cv::boundingRect(valid) & views.region;
	if (roi.empty())
		return;
	const double k = views.scale;
	// The roi's corner in the views, and in refinement pixels of the rectified frame.
	const int cx0 = int(std::lround((roi.x - views.region.x) * k));
	const int cy0 = int(std::lround((roi.y - views.region.y) * k));
	const cv::Size size(std::min(int(std::lround(roi.width * k)), views.left.cols - cx0),
			    std::min(int(std::lround(roi.height * k)), views.left.rows - cy0));
	if (size.width <= 0 || size.height <= 0)
		return;
	const double ox = views.region.x * k + cx0, oy = views.region.y * k + cy0;
	cv::Mat L, R;
	views.left(cv::Rect(cv::Point(cx0, cy0), size)).convertTo(L, CV_32F);
	views.right(cv::Rect(0, cy0, views.right.cols, size.height)).convertTo(R, CV_32F);
	// The disparity at full resolution (NaN-free: invalid pixels carry 0 and are masked).
	cv::Mat d0(roi.size(), CV_32F, cv::Scalar(0)), v32;
	(*disparity)(roi).copyTo(d0, valid(roi));
	valid(roi).convertTo(v32, CV_32F, 1.0 / 255);
	// Upsampled so that full-resolution pixel x reads matching pixel x / k, as the rectification
	// above puts it; cv::resize aligns pixel centres instead (x / k - 1/4 at k = 2), and every
	// refined pixel then moved by a quarter of the disparity's slope (test_dense's
	// refinement_starts_where_the_disparity_is).
	cv::Mat D, W;
	const cv::Matx23d to_matching(1 / k, 0, ox / k - roi.x, 0, 1 / k, oy / k - roi.y);
	cv::warpAffine(d0, D, to_matching, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
	cv::warpAffine(v32, W, to_matching, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
	// Normalised: bilinear weights on invalid neighbours (their 0) would pull a pixel next to a
	// hole towards disparity 0 (a quarter of it or more), a step the steep filter then cuts out.
	for (int y = 0; y < size.height; ++y) {
		float *dr = D.ptr<float>(y);
		const float *wr = W.ptr<float>(y);
		for (int x = 0; x < size.width; ++x)
			dr[x] = wr[x] > 1e-3f ? dr[x] / wr[x] : 0.f;
	}
	D *= k;
	const cv::Mat D_in = D.clone();
	const cv::Size win(params.refine_window, params.refine_window);
	// A window reaching into a hole would compare the left view with the right one warped by
	// the hole's disparity (none): only pixels whose whole window is matched are refined.
	cv::boxFilter(W, W, CV_32F, win);
	cv::Mat muL;
	cv::boxFilter(L, muL, CV_32F, win);
	const cv::Mat Lz = L - muL;
	cv::Mat mx(size, CV_32F), my(size, CV_32F);
	cv::Mat measured(size, CV_8U, cv::Scalar(0)); // pixels the refinement measured (stepped)
	for (int it = 0; it < params.refine_iterations; ++it) {
		for (int y = 0; y < size.height; ++y) {
			const float *dr = D.ptr<float>(y);
			float *xr = mx.ptr<float>(y), *yr = my.ptr<float>(y);
			for (int x = 0; x < size.width; ++x) {
				xr[x] = float(x + ox) - dr[x]; // the right view's column: it starts at 0
				yr[x] = float(y);
			}
		}
		cv::Mat Rw, g, muR, e, ge, gg, ng;
		cv::remap(R, Rw, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
		cv::Sobel(Rw, g, CV_32F, 1, 0, 3, 1.0 / 8);
		cv::boxFilter(Rw, muR, CV_32F, win);
		e = Lz - (Rw - muR); // zero-mean: an exposure offset between the cameras is not a shift
		cv::boxFilter(g.mul(e), ge, CV_32F, win);
		cv::boxFilter(g.mul(g), gg, CV_32F, win);
		// R(x - D - s) ≈ Rw(x) - s g, so the residual e = L - Rw is minimised by s = -Σge / Σgg.
		const float min_gg = float(params.refine_min_gradient * params.refine_min_gradient);
		for (int y = 0; y < size.height; ++y) {
			float *dr = D.ptr<float>(y);
			const float *ger = ge.ptr<float>(y), *ggr = gg.ptr<float>(y), *wr = W.ptr<float>(y);
			uchar *mr = measured.ptr<uchar>(y);
			for (int x = 0; x < size.width; ++x) {
				if (wr[x] < 0.99f || ggr[x] < min_gg)
					continue;
				const float step = std::clamp(-ger[x] / ggr[x], -0.5f, 0.5f);
				dr[x] += step;
				mr[x] = 255;
			}
		}
	}
	// Back to the matching resolution: each matching pixel moves by what the refinement moved the
	// full-resolution pixel at its place; one it did not refine keeps its own value exactly
	// (reading the upsampled map back would blend it with its neighbours).
	for (int y = 0; y < roi.height; ++y) {
		float *out = disparity->ptr<float>(roi.y + y) + roi.x;
		const uchar *vr = valid.ptr<uchar>(roi.y + y) + roi.x;
		const int yy = std::min(size.height - 1, int(std::lround((roi.y + y) * k - oy)));
		for (int x = 0; x < roi.width; ++x) {
			if (!vr[x])
				continue;
			const int xx = std::min(size.width - 1, int(std::lround((roi.x + x) * k - ox)));
			out[x] += (D.at<float>(yy, xx) - D_in.at<float>(yy, xx)) / float(k);
		}
	}
	const int ik = int(std::lround(k));
	if (ret_refined && ik >= 1 && std::fabs(k - ik) < 1e-9) {
		ret_refined->roi = roi;
		ret_refined->scale = ik;
		ret_refined->disparity = cv::Mat(size, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
		D.convertTo(D, CV_32F, 1.0 / k);
		D.copyTo(ret_refined->disparity, measured);
	}
}

int fill_flat_regions(const cv::Mat &grey_l, const cv::Mat &std_l, const DenseParams &params, cv::Mat *valid_io,
		      cv::Mat *total, DenseStats *stats)
{
	const cv::Mat &valid = *valid_io;
	cv::Mat flat = valid & (std_l <= float(params.flat_texture_std));
	cv::Mat labels, region, centroids;
	const int nr = cv::connectedComponentsWithStats(flat, labels, region, centroids, 4, CV_32S);
	if (nr <= 1)
		return 0;
	const size_t n_regions = size_t(nr);
	std::vector<double> area(n_regions), cx(n_regions), cy(n_regions);
	for (int l = 1; l < nr; ++l) {
		area[size_t(l)] = region.at<int>(l, cv::CC_STAT_AREA);
		cx[size_t(l)] = centroids.at<double>(l, 0);
		cy[size_t(l)] = centroids.at<double>(l, 1);
	}
	const int r = std::max(1, params.flat_ring_px);
	// The distinct labels > 0 of `m` (CV_32S) within r of (x, y) that `accept` takes, the first
	// `max` of them in scan order, into `seen`; returns how many.
	auto labels_near = [r](const cv::Mat &m, int x, int y, int max, auto &&accept, int *seen) {
		int ns = 0;
		for (int dy = -r; dy <= r && ns < max; ++dy) {
			const int yy = y + dy;
			if (yy < 0 || yy >= m.rows)
				continue;
			const int *row = m.ptr<int>(yy);
			for (int dx = -r; dx <= r && ns < max; ++dx) {
				const int xx = x + dx;
				if (xx < 0 || xx >= m.cols || row[xx] <= 0 || !accept(row[xx]))
					continue;
				if (std::find(seen, seen + ns, row[xx]) == seen + ns)
					seen[ns++] = row[xx];
			}
		}
		return ns;
	};
	// The ring's pixels, gathered once: (label, x, y, disparity).
	struct RingPixel {
		int label, x, y;
		float d;
	};
	std::vector<RingPixel> ring;
	std::vector<int> ring_count(n_regions, 0);
	std::vector<double> ring_grey(n_regions, 0.0), region_grey(n_regions, 0.0);
	for (int y = 0; y < valid.rows; ++y) {
		const uchar *vr = valid.ptr<uchar>(y), *fr = flat.ptr<uchar>(y), *gr = grey_l.ptr<uchar>(y);
		const int *lr0 = labels.ptr<int>(y);
		const float *tr = total->ptr<float>(y);
		for (int x = 0; x < valid.cols; ++x)
			if (fr[x] && lr0[x] > 0)
				region_grey[size_t(lr0[x])] += gr[x];
		for (int x = 0; x < valid.cols; ++x) {
			if (!vr[x] || fr[x])
				continue;
			// The flat regions this textured match borders (a few: the squares it separates,
			// more where the flat pixels are broken into specks).
			int seen[12];
			const int ns = labels_near(labels, x, y, 12, [](int) { return true; }, seen);
			for (int k = 0; k < ns; ++k) {
				ring.push_back({seen[k], x, y, tr[x]});
				ring_count[size_t(seen[k])]++;
				ring_grey[size_t(seen[k])] += gr[x];
			}
		}
	}
	// A flat region darker than its own edges is no lit square but a gap, a shadow or the band
	// between two projectors' zones: SGBM's guess there is carried in from the texture around it
	// and holds only near it (bench booth 101: dark flat points RMS 2-6 mm, bright ones 0.23).
	std::vector<char> dark(n_regions, 0);
	for (int l = 1; l < nr; ++l) {
		const size_t i = size_t(l);
		dark[i] = ring_count[i] == 0 || region_grey[i] / area[i] < ring_grey[i] / ring_count[i];
	}
	// A dark region of more than flat_tile_px² pixels is also cut by a grid of flat_tile_px into
	// pieces, labelled from nr on, each fitted from its own share of the ring: where the gaps join
	// into one lattice around many squares, one quadratic over the whole follows none of them
	// (fresh booth 4811: 20 dark regions of 34.5k px, fit RMS 2.3 px); its pieces do. A piece that
	// cannot be fitted (too little ring of its own) takes its region's fit. A large bright region
	// (a square's interior) is not cut: there its pieces, fitted to short stretches of edge near
	// the match's border, kept values the unfitted reach would drop (bench booth 111: RMS +0.002
	// to +0.020 mm on its four scenes with bright regions cut too).
	const int tile = params.flat_tile_px;
	cv::Mat pieces(labels.size(), CV_32S, cv::Scalar(0));
	std::vector<int> region_of; // of each piece, from nr on
	if (tile > 0) {
		const int64_t tiles_x = (labels.cols + tile - 1) / tile, tiles_y = (labels.rows + tile - 1) / tile;
		std::unordered_map<int64_t, int> piece_of; // (region, tile) -> label
		for (int y = 0; y < labels.rows; ++y) {
			const int *lr = labels.ptr<int>(y);
			int *pr = pieces.ptr<int>(y);
			for (int x = 0; x < labels.cols; ++x) {
				const int l = lr[x];
				if (l <= 0 || !dark[size_t(l)] || area[size_t(l)] <= double(tile) * tile)
					continue;
				const int64_t key = (l * tiles_y + y / tile) * tiles_x + x / tile;
				auto it = piece_of.emplace(key, int(area.size())).first;
				if (size_t(it->second) == area.size()) {
					area.push_back(0);
					cx.push_back(0);
					cy.push_back(0);
					region_of.push_back(l);
				}
				const size_t p = size_t(it->second);
				pr[x] = int(p);
				area[p] += 1;
				cx[p] += x;
				cy[p] += y;
			}
		}
		for (size_t p = n_regions; p < area.size(); ++p) {
			cx[p] /= area[p];
			cy[p] /= area[p];
		}
		// Each piece's ring: its region's ring pixels within flat_ring_px of the piece.
		const size_t region_ring = ring.size();
		for (size_t k = 0; k < region_ring; ++k) {
			const RingPixel q = ring[k];
			// 4 pieces at most while a tile is wider than the window.
			int seen[4];
			const int ns = labels_near(
				pieces, q.x, q.y, 4, [&](int p) { return region_of[size_t(p) - n_regions] == q.label; },
				seen);
			for (int j = 0; j < ns; ++j)
				ring.push_back({seen[j], q.x, q.y, q.d});
		}
		ring_count.resize(area.size(), 0);
		for (size_t k = region_ring; k < ring.size(); ++k)
			ring_count[size_t(ring[k].label)]++;
	}
	const int nl = int(area.size());
	using Mat6 = Eigen::Matrix<double, 6, 6>;
	using Vec6 = Eigen::Matrix<double, 6, 1>;
	std::vector<Mat6> ata(size_t(nl), Mat6::Zero());
	std::vector<Vec6> atb(size_t(nl), Vec6::Zero());
	std::vector<double> btb(size_t(nl), 0.0);
	std::vector<int> count(size_t(nl), 0);
	std::vector<double> scale(size_t(nl), 1.0);
	for (int l = 1; l < nl; ++l)
		scale[size_t(l)] = std::max(1.0, std::sqrt(area[size_t(l)]));
	auto basis = [&](int l, double x, double y) {
		const double s = scale[size_t(l)];
		const double u = (x - cx[size_t(l)]) / s, v = (y - cy[size_t(l)]) / s;
		Vec6 phi;
		phi << 1, u, v, u * u, u * v, v * v;
		return phi;
	};
	// A robust fit: least squares, then again on the ring pixels within a shrinking gate of the
	// previous fit (a square's edge may border a mismatch or another surface).
	std::vector<Vec6> coef(size_t(nl), Vec6::Zero());
	std::vector<char> fit(size_t(nl), 0);
	const double gates[3] = {1e9, 2.0 * params.flat_max_fit_px, params.flat_max_fit_px};
	for (double gate : gates) {
		for (int l = 0; l < nl; ++l) {
			ata[size_t(l)].setZero();
			atb[size_t(l)].setZero();
			btb[size_t(l)] = 0;
			count[size_t(l)] = 0;
		}
		for (const RingPixel &q : ring) {
			const size_t l = size_t(q.label);
			const Vec6 phi = basis(q.label, q.x, q.y);
			if (gate < 1e8 && (fit[l] <= 0 || std::fabs(coef[l].dot(phi) - q.d) > gate))
				continue;
			ata[l] += phi * phi.transpose();
			atb[l] += phi * double(q.d);
			btb[l] += double(q.d) * double(q.d);
			count[l]++;
		}
		for (int l = 1; l < nl; ++l) {
			const size_t i = size_t(l);
			fit[i] = 0; // a region unfitted in the last pass has no ring pixels in this one
			if (count[i] < params.flat_min_ring || count[i] < params.flat_min_inliers * ring_count[i])
				continue;
			Eigen::LDLT<Mat6> ldlt(ata[i]);
			if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-9))
				continue;
			coef[i] = ldlt.solve(atb[i]);
			const double sse = btb[i] - 2 * coef[i].dot(atb[i]) + coef[i].dot(ata[i] * coef[i]);
			const double rms = std::sqrt(std::max(0.0, sse) / count[i]);
			fit[i] = rms <= std::min(gate, 1e3) ? 1 : 0;
		}
	}
	// Where the ring is one-sided the quadratic is free on the open side: a fit that leaves the
	// range of the disparities it was fitted to is not used.
	if (params.flat_max_overshoot_px >= 0) {
		std::vector<float> lo(size_t(nl), std::numeric_limits<float>::max()),
			hi(size_t(nl), std::numeric_limits<float>::lowest());
		for (const RingPixel &q : ring) {
			const size_t l = size_t(q.label);
			if (fit[l] > 0 && std::fabs(coef[l].dot(basis(q.label, q.x, q.y)) - q.d) <= params.flat_max_fit_px) {
				lo[l] = std::min(lo[l], q.d);
				hi[l] = std::max(hi[l], q.d);
			}
		}
		const double m = params.flat_max_overshoot_px;
		for (int y = 0; y < valid.rows; ++y) {
			const int *lr = labels.ptr<int>(y), *pr = pieces.ptr<int>(y);
			for (int x = 0; x < valid.cols; ++x)
				for (const int l : {lr[x], pr[x]}) {
					const size_t i = size_t(std::max(0, l));
					if (i == 0 || fit[i] <= 0)
						continue;
					const double d = coef[i].dot(basis(l, x, y));
					if (d < lo[i] - m || d > hi[i] + m)
						fit[i] = 0;
				}
		}
	}
	cv::Mat from_texture;
	if (params.flat_dark_reach_px > 0 || params.flat_unfitted_reach_px > 0) {
		const cv::Mat textured = valid & ~flat;
		cv::distanceTransform(~textured, from_texture, cv::DIST_L2, 3);
	}
	int filled = 0;
	for (int y = 0; y < valid.rows; ++y) {
		const int *lr = labels.ptr<int>(y), *pr = pieces.ptr<int>(y);
		float *tr = total->ptr<float>(y);
		const float *fr = from_texture.empty() ? nullptr : from_texture.ptr<float>(y);
		uchar *vr = valid_io->ptr<uchar>(y);
		for (int x = 0; x < valid.cols; ++x) {
			const int l = lr[x];
			if (l <= 0)
				continue;
			if (fr && dark[size_t(l)] && params.flat_dark_reach_px > 0 &&
			    fr[x] > float(params.flat_dark_reach_px)) {
				vr[x] = 0;
				stats->flat_dropped++;
				continue;
			}
			const int used = pr[x] > 0 && fit[size_t(pr[x])] > 0 ? pr[x] : l;
			if (fit[size_t(used)] <= 0) {
				// Unfitted: SGBM's value holds only near the texture it was carried from.
				if (fr && !dark[size_t(l)] && params.flat_unfitted_reach_px > 0 &&
				    fr[x] > float(params.flat_unfitted_reach_px)) {
					vr[x] = 0;
					stats->flat_unfitted_dropped++;
				} else {
					stats->flat_kept++;
				}
				continue;
			}
			tr[x] = float(coef[size_t(used)].dot(basis(used, x, y)));
			filled++;
		}
	}
	stats->flat_filled += filled;
	return filled;
}

int bridge_dark_gaps(const cv::Mat &dark, double pitch_px, const DenseParams &params, cv::Mat *valid_io,
		     cv::Mat *total_io, cv::Mat *ret_bridged)
{
	cv::Mat &valid = *valid_io;
	const cv::Mat &total = *total_io;
	*ret_bridged = cv::Mat(valid.size(), CV_8U, cv::Scalar(0));
	const double width = params.dark_bridge_pitches * pitch_px;
	if (!(width >= 2))
		return 0;
	const int diameter = int(std::lround(width)) | 1;
	cv::Mat closed;
	cv::morphologyEx(valid, closed, cv::MORPH_CLOSE,
			 cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(diameter, diameter)));
	cv::Mat candidates = closed & ~valid & (dark != 0);
	std::vector<cv::Point> gap_pixels;
	cv::findNonZero(candidates, gap_pixels);
	if (gap_pixels.empty())
		return 0;
	// Every 2nd pixel of a wide window is enough for 6 unknowns.
	const int r = std::max(2, int(std::lround(params.dark_bridge_fit_pitches * pitch_px)));
	const int step = r > 8 ? 2 : 1;
	std::vector<float> value(gap_pixels.size(), std::numeric_limits<float>::quiet_NaN());
	const double max_fit = params.dark_bridge_max_fit_px;
	cv::parallel_for_(cv::Range(0, int(gap_pixels.size())), [&](const cv::Range &range) {
		using Mat6 = Eigen::Matrix<double, 6, 6>;
		using Vec6 = Eigen::Matrix<double, 6, 1>;
		std::vector<std::pair<Vec6, double>> samples;
		for (int i = range.start; i < range.end; ++i) {
			const cv::Point c = gap_pixels[size_t(i)];
			samples.clear();
			for (int y = std::max(0, c.y - r); y <= std::min(valid.rows - 1, c.y + r); y += step) {
				const uchar *vr = valid.ptr<uchar>(y);
				const float *tr = total.ptr<float>(y);
				for (int x = std::max(0, c.x - r); x <= std::min(valid.cols - 1, c.x + r); x += step) {
					if (!vr[x] || (x - c.x) * (x - c.x) + (y - c.y) * (y - c.y) > r * r)
						continue;
					const double u = double(x - c.x) / r, v = double(y - c.y) / r;
					Vec6 phi;
					phi << 1, u, v, u * u, u * v, v * v;
					samples.emplace_back(phi, double(tr[x]));
				}
			}
			if (samples.size() < 24)
				continue;
			// Least squares, then again on the samples within 2x and 1x the limit of the last
			// fit: a mismatched edge pixel of a square does not veto the gap.
			Vec6 coef = Vec6::Zero();
			bool fitted = false;
			double rss = 0;
			int inliers = 0;
			for (int round = 0; round < 3; ++round) {
				const double limit = round == 0 ? HUGE_VAL : (round == 1 ? 2 : 1) * max_fit;
				Mat6 ata = Mat6::Zero();
				Vec6 atb = Vec6::Zero();
				double btb = 0;
				int n = 0;
				for (const auto &[phi, d] : samples) {
					if (fitted && std::fabs(phi.dot(coef) - d) > limit)
						continue;
					ata += phi * phi.transpose();
					atb += phi * d;
					btb += d * d;
					n++;
				}
				if (n < 24)
					break;
				const Eigen::LDLT<Mat6> ldlt(ata);
				if (ldlt.info() != Eigen::Success)
					break;
				coef = ldlt.solve(atb);
				fitted = coef.allFinite();
				if (!fitted)
					break;
				rss = btb - coef.dot(atb); // residual sum of squares of the fit
				inliers = n;
			}
			if (!(fitted && inliers >= 24 && 10 * inliers >= 7 * int(samples.size()) &&
			      rss <= max_fit * max_fit * inliers))
				continue;
			// Samples on the two sides of a gap leave a quadratic free to bend through a step
			// between two surfaces; a face's disparity bends by a fraction of a pixel over a
			// window this size (a sphere of 80 mm bulges 0.1 mm over 8 mm), so a fit that bends
			// by more than `dark_bridge_max_bend_px` at the window's edge is not a surface.
			const double bend = std::fabs(coef[3]) + 0.5 * std::fabs(coef[4]) + std::fabs(coef[5]);
			if (bend > params.dark_bridge_max_bend_px)
				continue;
			// The matches that fit lie around it on every side (each quadrant has some), so the
			// fit interpolates across the gap: beside a step only one side's surface fits.
			int quadrant[4] = {0, 0, 0, 0};
			for (const auto &[phi, d] : samples)
				if (std::fabs(phi.dot(coef) - d) <= max_fit)
					quadrant[(phi[1] > 0) + 2 * (phi[2] > 0)]++;
			if (std::min({quadrant[0], quadrant[1], quadrant[2], quadrant[3]}) >= 3)
				value[size_t(i)] = float(coef[0]);
		}
	});
	int bridged = 0;
	for (size_t i = 0; i < gap_pixels.size(); ++i) {
		if (value[i] != value[i])
			continue;
		const cv::Point c = gap_pixels[i];
		total_io->at<float>(c) = value[i];
		ret_bridged->at<uchar>(c) = 255;
		bridged++;
	}
	valid |= *ret_bridged;
	return bridged;
}

cv::Mat has_value(const cv::Mat &map)
{
	// Not `map == map`: OpenCV's vectorised compare does not keep IEEE semantics for NaN.
	CV_Assert(map.type() == CV_32F);
	cv::Mat out(map.size(), CV_8U);
	for (int y = 0; y < map.rows; ++y) {
		const float *r = map.ptr<float>(y);
		uchar *o = out.ptr<uchar>(y);
		for (int x = 0; x < map.cols; ++x)
			o[x] = std::isnan(r[x]) ? 0 : 255;
	}
	return out;
}

Status rectify_pair(const CameraModel &a, const CameraModel &b, double scale, RectifiedPair *ret)
{
	if (!(scale > 0.05 && scale <= 2))
		return Status::error(-EINVAL, "dense: matching scale must be in (0.05, 2]");
	const cv::Matx33d R = b.R * a.R.t();
	const cv::Vec3d T = b.T - R * a.T;
	if (cv::norm(T) < 1e-6)
		return Status::error(-EINVAL, "dense: the pair's cameras are at the same place");
	// stereoRectify's rotations (half of the relative rotation each, then the smallest turn of the
	// baseline onto an axis), but always onto -x in b's half-turned frame, i.e. b to the right of a:
	// stereoRectify turns it onto y when the baseline is more vertical than horizontal in that
	// frame (random booth 204, pair 2-3: b 45 degrees down and to the right, |t_y| > |t_x|), and
	// the rows then run across the baseline. For pairs it rectifies along x this is its own result.
	cv::Vec3d om;
	cv::Rodrigues(cv::Mat(R), om);
	cv::Matx33d r_r;
	cv::Rodrigues(om * -0.5, r_r);
	const cv::Vec3d t = r_r * T;
	const cv::Vec3d target(-1, 0, 0);
	cv::Vec3d w = t.cross(target);
	const double nw = cv::norm(w), angle = std::acos(std::clamp(t.dot(target) / cv::norm(t), -1.0, 1.0));
	if (nw > 1e-12 * cv::norm(t))
		w *= angle / nw;
	else if (angle > 1.0)
		w = cv::Vec3d(0, 0, CV_PI); // b exactly to the left: half a turn about the optical axis
	else
		w = cv::Vec3d(0, 0, 0);
	cv::Matx33d wR;
	cv::Rodrigues(w, wR);
	RectifiedPair rp;
	rp.R1 = wR * r_r.t();
	rp.R2 = wR * r_r;
	const cv::Mat R1(rp.R1), R2(rp.R2);
	rp.size = cv::Size(int(std::lround(a.size.width * scale)), int(std::lround(a.size.height * scale)));
	rp.f = scale * (a.K(0, 0) + a.K(1, 1) + b.K(0, 0) + b.K(1, 1)) / 4;
	// Each camera's optical axis lands at the centre of its rectified image: converging cameras
	// rotate apart, and one shared principal point would push one view out of the image.
	const cv::Vec3d za = rp.R1 * cv::Vec3d(0, 0, 1), zb = rp.R2 * cv::Vec3d(0, 0, 1);
	if (za[2] < 0.2 || zb[2] < 0.2)
		return Status::error(-EINVAL, "dense: the pair's cameras converge by more than 78 degrees");
	rp.cx1 = rp.size.width / 2.0 - rp.f * za[0] / za[2];
	rp.cx2 = rp.size.width / 2.0 - rp.f * zb[0] / zb[2];
	rp.cy = rp.size.height / 2.0 - rp.f * (za[1] / za[2] + zb[1] / zb[2]) / 2;
	const cv::Vec3d cb = rp.R1 * (-(R.t() * T)); // b's centre in a's rectified frame
	rp.baseline = cb[0];
	if (std::fabs(cb[1]) + std::fabs(cb[2]) > 1e-6 * cv::norm(cb) + 1e-9)
		return Status::error(-EINVAL, "dense: rectification left the baseline off the x axis");
	cv::initUndistortRectifyMap(cv::Mat(a.K), cv::Mat(a.dist), R1, cv::Mat(rectified_K(rp, 0)), rp.size,
				    CV_32FC1, rp.map1x, rp.map1y);
	cv::initUndistortRectifyMap(cv::Mat(b.K), cv::Mat(b.dist), R2, cv::Mat(rectified_K(rp, 1)), rp.size,
				    CV_32FC1, rp.map2x, rp.map2y);
	*ret = std::move(rp);
	return {};
}

std::vector<cv::Point2d> rectify_points(const RectifiedPair &rp, const CameraModel &cam, int which,
					const std::vector<cv::Point2d> &pixels)
{
	std::vector<cv::Point2d> out;
	if (pixels.empty())
		return out;
	cv::undistortPoints(pixels, out, cv::Mat(cam.K), cv::Mat(cam.dist), cv::Mat(which == 0 ? rp.R1 : rp.R2),
			    cv::Mat(rectified_K(rp, which)),
			    cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 1e-9));
	return out;
}

cv::Point3d rectified_to_world(const RectifiedPair &rp, const CameraModel &a, double x, double y, double d)
{
	// x_a = f X/Z + cx1 and x_b = f (X - baseline)/Z + cx2, so d = f baseline / Z + cx1 - cx2.
	const double z = rp.f * rp.baseline / (d - (rp.cx1 - rp.cx2));
	const cv::Vec3d rect((x - rp.cx1) * z / rp.f, (y - rp.cy) * z / rp.f, z);
	const cv::Vec3d cam = rp.R1.t() * rect;
	return cv::Point3d(a.R.t() * (cam - a.T));
}

cv::Mat disparity_prior(cv::Size size, const std::vector<cv::Point2d> &seeds_left,
			const std::vector<double> &seed_disparity, double max_edge_factor, double extrapolate_spacings,
			double *ret_median_spacing_px)
{
	cv::Mat prior(size, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
	if (ret_median_spacing_px)
		*ret_median_spacing_px = 0;
	if (seeds_left.size() < 3)
		return prior;
	const std::vector<cv::Vec3i> tris = delaunay_2d(seeds_left);
	std::vector<double> edges;
	edges.reserve(tris.size() * 3);
	for (const cv::Vec3i &t : tris)
		for (int k = 0; k < 3; ++k)
			edges.push_back(cv::norm(seeds_left[size_t(t[k])] - seeds_left[size_t(t[(k + 1) % 3])]));
	const double spacing = median(edges);
	if (ret_median_spacing_px)
		*ret_median_spacing_px = spacing;
	const double max_edge = max_edge_factor * spacing;
	for (const cv::Vec3i &t : tris) {
		cv::Point2d p[3];
		double d[3], longest = 0;
		for (int k = 0; k < 3; ++k) {
			p[k] = seeds_left[size_t(t[k])];
			d[k] = seed_disparity[size_t(t[k])];
			longest = std::max(longest, cv::norm(seeds_left[size_t(t[k])] - seeds_left[size_t(t[(k + 1) % 3])]));
		}
		if (longest <= max_edge)
			fill_triangle(&prior, p, d);
	}
	// Past the rim: the nearest prior value, out to `extrapolate_spacings` seed spacings.
	const double reach = extrapolate_spacings * spacing;
	if (reach < 1)
		return prior;
	cv::Mat invalid = ~has_value(prior);
	if (cv::countNonZero(invalid) == invalid.rows * invalid.cols)
		return prior;
	cv::Mat dist, labels;
	cv::distanceTransform(invalid, dist, labels, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
	std::vector<float> value_of_label(1, 0.f);
	for (int y = 0; y < prior.rows; ++y) {
		const float *row = prior.ptr<float>(y);
		for (int x = 0; x < prior.cols; ++x)
			if (row[x] == row[x])
				value_of_label.push_back(row[x]);
	}
	for (int y = 0; y < prior.rows; ++y) {
		float *row = prior.ptr<float>(y);
		const float *dr = dist.ptr<float>(y);
		const int *lr = labels.ptr<int>(y);
		for (int x = 0; x < prior.cols; ++x)
			if (row[x] != row[x] && dr[x] <= reach && lr[x] > 0 && size_t(lr[x]) < value_of_label.size())
				row[x] = value_of_label[size_t(lr[x])];
	}
	return prior;
}

Status prepare_pair(const cv::Mat &frame_a, const cv::Mat &frame_b, const CameraModel &a, const CameraModel &b,
		    const PartialModel &model, const DenseParams &params, PreparedPair *ret)
{
	if (frame_a.empty() || frame_b.empty() || frame_a.type() != CV_8UC3 || frame_b.type() != CV_8UC3)
		return Status::error(-EINVAL, "dense: frames must be 8-bit 3-channel");
	if (params.residual_px < 1 || params.residual_px > 64 || params.block < 1 || params.block % 2 == 0)
		return Status::error(-EINVAL, "dense: residual_px must be 1..64 and block odd");
	PreparedPair pp;
	pp.params = params;
	pp.frame_b = frame_b;
	pp.a = a;
	pp.b = b;
	pp.cam_a = model.cam_a;
	pp.cam_b = model.cam_b;
	Status s = rectify_pair(a, b, params.scale, &pp.rp);
	if (!s.ok())
		return s;
	const RectifiedPair &rp = pp.rp;

	// Seeds: the sparse model's matches in rectified coordinates.
	std::vector<cv::Point2d> pa, pb;
	pa.reserve(model.sources.size());
	pb.reserve(model.sources.size());
	for (const PointMatch &m : model.sources) {
		pa.push_back(m.a);
		pb.push_back(m.b);
	}
	const std::vector<cv::Point2d> ra = rectify_points(rp, a, 0, pa), rb = rectify_points(rp, b, 1, pb);
	for (size_t i = 0; i < ra.size(); ++i) {
		if (!(ra[i].x >= 0 && ra[i].y >= 0 && ra[i].x < rp.size.width && ra[i].y < rp.size.height))
			continue;
		pp.seeds.push_back(ra[i]);
		pp.seed_d.push_back(ra[i].x - rb[i].x);
	}
	cv::remap(frame_a, pp.left, rp.map1x, rp.map1y, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
	cv::cvtColor(pp.left, pp.grey_l, cv::COLOR_BGR2GRAY);
	pp.grey_l.convertTo(pp.grey_l32, CV_32F);
	code_prior(&pp);
	// A match keeps only lit pixels, so the refinement never reads beyond their bounding box.
	if (params.refine_iterations > 0)
		pp.refine = refine_views(frame_a, frame_b, a, b, rp, params.refine_scale, cv::boundingRect(pp.lit));
	*ret = std::move(pp);
	return {};
}

Status match_pair(const PreparedPair &pp, const std::vector<cv::Point3f> *guide, DenseCloud *ret_cloud,
		  DenseStats *ret_stats, DensePairDebug *ret_debug)
{
	if (pp.left.empty())
		return Status::error(-EINVAL, "dense: the pair is not prepared");
	const DenseParams &params = pp.params;
	const RectifiedPair &rp = pp.rp;
	const CameraModel &a = pp.a;
	const cv::Mat &frame_b = pp.frame_b, &left = pp.left, &grey_l = pp.grey_l, &grey_l32 = pp.grey_l32,
		      &lit = pp.lit;
	DenseStats stats;
	stats.seeds = int(pp.seeds.size());
	stats.median_spacing_px = pp.median_spacing_px;
	stats.seed_cover = pp.seed_cover;
	DenseCloud cloud;
	cloud.cam_a = pp.cam_a;
	cloud.cam_b = pp.cam_b;
	cv::Mat prior = match_prior(pp, guide, &stats);
	// Why each pixel has no point, for the debug output only.
	const bool why = ret_debug != nullptr;
	cv::Mat reason;
	if (why)
		reason = cv::Mat(rp.size, CV_8U, cv::Scalar(kReasonNoPrior));
	// Only where the pattern falls.
	for (int y = 0; y < prior.rows; ++y) {
		float *pr = prior.ptr<float>(y);
		const uchar *lr = lit.ptr<uchar>(y);
		for (int x = 0; x < prior.cols; ++x)
			if (pr[x] == pr[x] && !lr[x]) {
				pr[x] = std::numeric_limits<float>::quiet_NaN();
				stats.unlit++;
				if (why)
					reason.at<uchar>(y, x) = kReasonUnlit;
			}
	}

	// The left view rectified; the right one rectified and warped by the prior in one remap:
	// warped(x, y) = right_rectified(x - prior(x, y), y).
	cv::Mat warped;
	cv::Mat wx(rp.size, CV_32F), wy(rp.size, CV_32F);
	for (int y = 0; y < rp.size.height; ++y) {
		const float *pr = prior.ptr<float>(y);
		float *xr = wx.ptr<float>(y), *yr = wy.ptr<float>(y);
		for (int x = 0; x < rp.size.width; ++x) {
			const bool ok = pr[x] == pr[x];
			stats.prior_pixels += ok;
			xr[x] = ok ? float(x) - pr[x] : -1e4f;
			yr[x] = float(y);
		}
	}
	cv::Mat mx, my;
	cv::remap(rp.map2x, mx, wx, wy, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(-1e4));
	cv::remap(rp.map2y, my, wx, wy, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(-1e4));
	cv::remap(frame_b, warped, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT);

	const int cn = left.channels();
	const int nd = ((2 * params.residual_px + 15) / 16) * 16;
	const int mind = -nd / 2;
	cv::Ptr<cv::StereoSGBM> sgbm = cv::StereoSGBM::create(
		mind, nd, params.block, params.p1_factor * cn * params.block * params.block,
		params.p2_factor * cn * params.block * params.block, params.disp12_max_diff, 31, params.uniqueness,
		params.speckle_window, params.speckle_range, cv::StereoSGBM::MODE_SGBM_3WAY);
	// SGBM over the bounding box of the prior only (plus its own margins).
	cv::Mat disp16(rp.size, CV_16S, cv::Scalar((mind - 1) * 16));
	{
		cv::Rect roi = cv::boundingRect(has_value(prior));
		if (!roi.empty()) {
			const int m = nd + params.block + 4;
			roi = cv::Rect(roi.x - m, roi.y - params.block, roi.width + 2 * m, roi.height + 2 * params.block) &
			      cv::Rect(cv::Point(0, 0), rp.size);
			if (roi.width > nd + params.block + 1) {
				cv::Mat d;
				sgbm->compute(left(roi), warped(roi), d);
				d.copyTo(disp16(roi));
			}
		}
	}

	// Confidence: NCC of the left window and the right window at the matched disparity.
	cv::Mat grey_w, grey_w32;
	cv::cvtColor(warped, grey_w, cv::COLOR_BGR2GRAY);
	cv::Mat rx(rp.size, CV_32F), ry(rp.size, CV_32F);
	for (int y = 0; y < rp.size.height; ++y) {
		const short *dr = disp16.ptr<short>(y);
		float *xr = rx.ptr<float>(y), *yr = ry.ptr<float>(y);
		for (int x = 0; x < rp.size.width; ++x) {
			xr[x] = dr[x] >= mind * 16 ? float(x) - dr[x] / 16.f : float(x);
			yr[x] = float(y);
		}
	}
	cv::Mat matched_w;
	cv::remap(grey_w, matched_w, rx, ry, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
	matched_w.convertTo(grey_w32, CV_32F);
	cv::Mat ncc, std_l;
	window_ncc(grey_l32, grey_w32, params.block, &ncc, &std_l);

	// Valid pixels: a prior, lit in both views, matched by SGBM (its left-right check passed).
	cv::Mat valid(rp.size, CV_8U, cv::Scalar(0));
	cv::Mat total(rp.size, CV_32F, cv::Scalar(0));
	cv::Mat fail(rp.size, CV_8U, cv::Scalar(0)); // SGBM found no match (its checks refused one)
	cv::Mat dark(rp.size, CV_8U, cv::Scalar(0)); // a prior, too dark to match in either view
	for (int y = 0; y < rp.size.height; ++y) {
		const short *dr = disp16.ptr<short>(y);
		const float *pr = prior.ptr<float>(y);
		const uchar *gl = grey_l.ptr<uchar>(y), *gw = matched_w.ptr<uchar>(y);
		const float *nr = ncc.ptr<float>(y), *sr = std_l.ptr<float>(y);
		uchar *vr = valid.ptr<uchar>(y);
		float *tr = total.ptr<float>(y);
		for (int x = 0; x < rp.size.width; ++x) {
			if (pr[x] != pr[x])
				continue;
			uchar dummy = 0;
			uchar &rr = why ? reason.at<uchar>(y, x) : dummy;
			if (dr[x] < mind * 16) {
				fail.at<uchar>(y, x) = 255;
				rr = kReasonRefused;
				continue;
			}
			if (gl[x] < params.min_intensity || gw[x] < params.min_intensity) {
				dark.at<uchar>(y, x) = 255;
				rr = kReasonDark;
				continue;
			}
			stats.matched++;
			// Inside a flat square the window has no texture and NCC says nothing: SGBM's
			// smoothness carries the disparity across it from the square's edges.
			if (sr[x] > 4 && nr[x] < params.min_confidence) {
				stats.low_confidence++;
				rr = kReasonLowConfidence;
				continue;
			}
			const float r = dr[x] / 16.f;
			// At the edge of the search the true match may lie outside it.
			if (std::fabs(r) > float(params.residual_px) - params.edge_margin_px) {
				stats.at_search_edge++;
				rr = kReasonSearchEdge;
				continue;
			}
			rr = kReasonKept;
			// The prior is read where the match landed: d = r + prior(x - r).
			const int xs = int(std::lround(x - r));
			const float p = xs >= 0 && xs < rp.size.width && pr[xs] == pr[xs] ? pr[xs] : pr[x];
			tr[x] = r + p;
			vr[x] = 255;
		}
	}
	// Next to a pixel SGBM refused (its left-right, uniqueness or speckle check) the match is
	// unsure; next to one merely dark or unlit it is not.
	if (params.unmatched_margin_px > 0) {
		const int m = 2 * params.unmatched_margin_px + 1;
		cv::Mat near;
		cv::dilate(fail, near, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(m, m)));
		near &= valid;
		stats.near_unmatched = cv::countNonZero(near);
		valid.setTo(0, near);
		if (why)
			reason.setTo(kReasonNearRefused, near);
	}
	RefinedDisparity refined;
	cv::Mat total_refined; // what the refinement left, to tell the pixels changed after it
	if (params.refine_iterations > 0) {
		refine_subpixel(pp.refine, valid, params, &total, params.points_at_refine_scale ? &refined : nullptr);
		if (refined.scale > 1)
			total_refined = total.clone();
	}
	if (params.flat_fill) {
		const cv::Mat before = why ? valid.clone() : cv::Mat();
		fill_flat_regions(grey_l, std_l, params, &valid, &total, &stats);
		if (why)
			reason.setTo(kReasonFlatDropped, before & ~valid);
	}
	// Before the rim and islands are judged: a dim booth's dark gaps between the squares are not
	// the matched region's border.
	cv::Mat bridged;
	if (params.dark_bridge_pitches > 0) {
		const double pitch = stats.median_spacing_px > 0 ? 2 * stats.median_spacing_px : params.default_pitch_px;
		stats.dark_bridged = bridge_dark_gaps(dark, pitch, params, &valid, &total, &bridged);
		if (why)
			reason.setTo(kReasonKept, bridged);
	}
	// Steep disparity (a surface seen edge-on, or an occluding contour SGBM smears across) and the
	// rim of the matched region are where matches go wrong: both are trimmed.
	{
		cv::Mat bad = steep_pixels(valid, total, params);
		if (params.rim_px > 0) {
			// Only the region's outline is a rim: pinholes SGBM left inside it are not widened.
			const cv::Mat eroded = erode_outline(valid, params.pinhole_px, params.rim_px, cv::MORPH_RECT);
			cv::Mat rim = valid & ~eroded;
			stats.rim += cv::countNonZero(rim);
			if (why)
				reason.setTo(kReasonRim, rim);
			valid = eroded;
		}
		cv::dilate(bad, bad, cv::Mat(), cv::Point(-1, -1), 1);
		cv::Mat steep = valid & bad;
		stats.steep += cv::countNonZero(steep);
		if (why)
			reason.setTo(kReasonSteep, steep);
		valid.setTo(0, bad);
	}
	// Islands are mismatches (a lit speck of hair, the rim of a shadow): only regions of at least
	// `min_region_px` pixels stay.
	{
		cv::Mat labels, region_stats, centroids;
		const int nl = cv::connectedComponentsWithStats(valid, labels, region_stats, centroids, 4, CV_32S);
		std::vector<char> keep(size_t(nl), 0);
		for (int l = 1; l < nl; ++l)
			keep[size_t(l)] = region_stats.at<int>(l, cv::CC_STAT_AREA) >= params.min_region_px;
		for (int y = 0; y < rp.size.height; ++y) {
			const int *lr = labels.ptr<int>(y);
			uchar *vr = valid.ptr<uchar>(y);
			for (int x = 0; x < rp.size.width; ++x)
				if (vr[x] && !keep[size_t(lr[x])]) {
					vr[x] = 0;
					stats.islands++;
					if (why)
						reason.at<uchar>(y, x) = kReasonIsland;
				}
		}
	}
	cv::Mat border_px;
	cv::distanceTransform(valid, border_px, cv::DIST_L2, 3);
	cloud.points.reserve(size_t(stats.matched));
	// One point at rectified (x, y) with disparity d, carrying matching pixel (px, py)'s
	// confidence and border distance.
	auto add_point = [&](double x, double y, double d, int px, int py) {
		const double den = d - (rp.cx1 - rp.cx2);
		if (std::fabs(den) < 1e-6 || rp.f * rp.baseline / den <= 0)
			return;
		const double z = rp.f * rp.baseline / den;
		cloud.points.emplace_back(rectified_to_world(rp, a, x, y, d));
		const bool interpolated = std_l.at<float>(py, px) <= 4 || (!bridged.empty() && bridged.at<uchar>(py, px));
		cloud.confidence.push_back(interpolated ? float(params.flat_confidence)
							: std::clamp(ncc.at<float>(py, px), 0.f, 1.f));
		cloud.border_mm.push_back(float(border_px.at<float>(py, px) * z / rp.f));
	};
	// The refinement's measurement at camera pixel (u, v) of its grid, when it made one there, the
	// matching pixels it lies between are all still matched, and the one it belongs to kept the
	// refinement's value (flat refill changes some); NaN otherwise.
	const int rk = refined.scale;
	auto measured_at = [&](int x, int y, int i, int j) {
		const float nan = std::numeric_limits<float>::quiet_NaN();
		const int u = (x - refined.roi.x) * rk + i, v = (y - refined.roi.y) * rk + j;
		if (u < 0 || v < 0 || u >= refined.disparity.cols || v >= refined.disparity.rows)
			return nan;
		if (x + (i > 0) >= rp.size.width || y + (j > 0) >= rp.size.height)
			return nan;
		for (int dy = 0; dy <= (j > 0); ++dy)
			for (int dx = 0; dx <= (i > 0); ++dx)
				if (!valid.at<uchar>(y + dy, x + dx))
					return nan;
		if (total.at<float>(y, x) != total_refined.at<float>(y, x))
			return nan;
		return refined.disparity.at<float>(v, u);
	};
	for (int y = 0; y < rp.size.height; ++y) {
		const uchar *vr = valid.ptr<uchar>(y);
		const float *tr = total.ptr<float>(y);
		for (int x = 0; x < rp.size.width; ++x) {
			if (!vr[x])
				continue;
			// The matching pixel's own point; with the refinement's resolution, the camera
			// pixels between it and the next matching pixels that the refinement measured.
			add_point(x, y, tr[x], x, y);
			if (rk < 2)
				continue;
			for (int j = 0; j < rk; ++j)
				for (int i = 0; i < rk; ++i) {
					if (i == 0 && j == 0)
						continue;
					const float d = measured_at(x, y, i, j);
					if (d == d)
						add_point(x + double(i) / rk, y + double(j) / rk, d, x, y);
				}
		}
	}
	stats.points = int(cloud.points.size());
	if (ret_debug) {
		ret_debug->left = left;
		ret_debug->warped = warped;
		ret_debug->prior = prior;
		ret_debug->disparity = cv::Mat(rp.size, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
		total.copyTo(ret_debug->disparity, valid);
		ret_debug->reason = reason;
		// rectified = R1 (R_a X + T_a), then the rectified pinhole (f, cx1, cy).
		const cv::Matx33d k(rp.f, 0, rp.cx1, 0, rp.f, rp.cy, 0, 0, 1);
		const cv::Matx33d r = k * rp.R1 * a.R;
		const cv::Vec3d t = k * (rp.R1 * a.T);
		ret_debug->world_to_left = cv::Matx34d(r(0, 0), r(0, 1), r(0, 2), t[0], r(1, 0), r(1, 1), r(1, 2), t[1],
						       r(2, 0), r(2, 1), r(2, 2), t[2]);
	}
	*ret_cloud = std::move(cloud);
	if (ret_stats)
		*ret_stats = stats;
	return {};
}

Status dense_pair(const cv::Mat &frame_a, const cv::Mat &frame_b, const CameraModel &a, const CameraModel &b,
		  const PartialModel &model, const DenseParams &params, DenseCloud *ret_cloud,
		  DenseStats *ret_stats, DensePairDebug *ret_debug, const std::vector<cv::Point3f> *guide)
{
	PreparedPair pp;
	const Status s = prepare_pair(frame_a, frame_b, a, b, model, params, &pp);
	if (!s.ok())
		return s;
	return match_pair(pp, guide, ret_cloud, ret_stats, ret_debug);
}

} // namespace facescan::recon
