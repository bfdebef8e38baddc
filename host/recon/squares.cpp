// Stage 1b: the pattern's squares on the intensity plane.
//
// A local-mean threshold separates lit squares from the dark gaps whatever the shading; each blob
// is then re-thresholded at the midpoint of its own inside and gap levels, which is where a
// symmetric blur leaves a step edge, so the mask's boundary is unbiased for the corner stage.
#include "recon/image_stages.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace facescan::recon {

namespace {

double median_of(std::vector<float> &v)
{
	if (v.empty())
		return 0;
	auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
	std::nth_element(v.begin(), mid, v.end());
	return *mid;
}

// Lit pixels: brighter than the local mean by a small margin (flat dark areas stay dark).
cv::Mat local_mean_mask(const cv::Mat &intensity, int window)
{
	window = std::max(3, window | 1);
	cv::Mat mean;
	cv::boxFilter(intensity, mean, CV_32F, cv::Size(window, window), cv::Point(-1, -1), true,
		      cv::BORDER_REPLICATE);
	cv::Mat mask(intensity.size(), CV_8U);
	for (int y = 0; y < intensity.rows; y++) {
		const float *i = intensity.ptr<float>(y), *m = mean.ptr<float>(y);
		uchar *o = mask.ptr<uchar>(y);
		for (int x = 0; x < intensity.cols; x++)
			o[x] = i[x] > m[x] * 1.05f + 2.0f ? 255 : 0;
	}
	return mask;
}

struct Component {
	cv::Rect box;
	int area;
	int label;
};

std::vector<Component> components(const cv::Mat &mask, double min_area, cv::Mat *labels)
{
	cv::Mat stats, centroids;
	int n = cv::connectedComponentsWithStats(mask, *labels, stats, centroids, 4, CV_32S);
	std::vector<Component> out;
	for (int l = 1; l < n; l++) {
		int area = stats.at<int>(l, cv::CC_STAT_AREA);
		if (area < min_area)
			continue;
		cv::Rect box(stats.at<int>(l, cv::CC_STAT_LEFT), stats.at<int>(l, cv::CC_STAT_TOP),
			     stats.at<int>(l, cv::CC_STAT_WIDTH), stats.at<int>(l, cv::CC_STAT_HEIGHT));
		// Compact blobs only: a square fills at least half of its bounding box whatever its
		// rotation, a long streak (an edge of the face, a highlight) does not.
		if (area < 0.4 * box.area())
			continue;
		out.push_back({box, area, l});
	}
	return out;
}

double median_area(const std::vector<Component> &comps)
{
	std::vector<float> a;
	for (const Component &c : comps)
		a.push_back(float(c.area));
	return median_of(a);
}

// The squares of one local-mean pass: the threshold at `window`, compact blobs, each
// re-thresholded at its own midpoint and kept when solid. Blobs larger than `max_area` are
// skipped before the costly part (merged squares, a lit wall). `side` sets the re-threshold's
// margin.
struct Pass {
	std::vector<Square> squares;
	std::vector<SquareBlob> blobs;
	std::vector<float> skipped_areas; // component areas over max_area
};

Pass extract(const cv::Mat &intensity, const SquareParams &params, const cv::Mat &labels,
	     const std::vector<Component> &comps, double side, double max_area)
{
	Pass out;
	std::vector<float> inside, outside;
	int margin = std::max(2, int(std::lround(0.2 * side)));
	cv::Rect frame(0, 0, intensity.cols, intensity.rows);
	for (const Component &c : comps) {
		if (c.area > max_area) {
			out.skipped_areas.push_back(float(c.area));
			continue;
		}
		cv::Rect box(c.box.x - margin, c.box.y - margin, c.box.width + 2 * margin,
			     c.box.height + 2 * margin);
		box &= frame;
		cv::Mat lab = labels(box), img = intensity(box);
		inside.clear();
		outside.clear();
		cv::Mat own = (lab == c.label);
		cv::Mat grown;
		cv::dilate(own, grown, cv::Mat(), cv::Point(-1, -1), 1);
		for (int y = 0; y < box.height; y++) {
			const int *l = lab.ptr<int>(y);
			const float *v = img.ptr<float>(y);
			const uchar *g = grown.ptr<uchar>(y);
			for (int x = 0; x < box.width; x++) {
				if (l[x] == c.label)
					inside.push_back(v[x]);
				else if (!g[x] && l[x] == 0)
					outside.push_back(v[x]);
			}
		}
		if (outside.size() < 8)
			continue;
		double in = median_of(inside), out_level = median_of(outside);
		if (in <= 0 || (in - out_level) / in < params.min_contrast)
			continue;
		float mid = float(0.5 * (in + out_level));
		// Re-threshold at the square's own midpoint, within reach of the first-pass blob only.
		cv::Mat reach;
		cv::dilate(own, reach, cv::Mat(), cv::Point(-1, -1), std::max(1, margin - 1));
		cv::Mat refined = (img > mid) & reach;
		cv::Mat rlab, rstats, rcent;
		int n = cv::connectedComponentsWithStats(refined, rlab, rstats, rcent, 4, CV_32S);
		int best = 0, best_area = 0;
		for (int l = 1; l < n; l++)
			if (rstats.at<int>(l, cv::CC_STAT_AREA) > best_area) {
				best_area = rstats.at<int>(l, cv::CC_STAT_AREA);
				best = l;
			}
		if (!best || best_area < params.min_area_px)
			continue;
		cv::Rect rb(rstats.at<int>(best, cv::CC_STAT_LEFT), rstats.at<int>(best, cv::CC_STAT_TOP),
			    rstats.at<int>(best, cv::CC_STAT_WIDTH), rstats.at<int>(best, cv::CC_STAT_HEIGHT));
		// Touching the search box means it merged with something: not a square.
		if ((rb.x == 0 && box.x > 0) || (rb.y == 0 && box.y > 0) ||
		    (rb.x + rb.width == box.width && box.x + box.width < frame.width) ||
		    (rb.y + rb.height == box.height && box.y + box.height < frame.height))
			continue;
		cv::Mat m = (rlab(rb) == best);
		std::vector<std::vector<cv::Point>> contours;
		cv::findContours(m, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
		if (contours.empty())
			continue;
		size_t ci = 0;
		for (size_t k = 1; k < contours.size(); k++)
			if (contours[k].size() > contours[ci].size())
				ci = k;
		std::vector<cv::Point> hull;
		cv::convexHull(contours[ci], hull);
		double hull_area = cv::contourArea(hull);
		// Pixel areas exceed polygon areas by about half a perimeter.
		double poly_area = hull_area + 0.5 * cv::arcLength(hull, true);
		if (poly_area <= 0 || best_area / poly_area < params.min_solidity)
			continue;
		cv::Moments mo = cv::moments(m, true);
		SquareBlob blob;
		blob.box = cv::Rect(box.x + rb.x, box.y + rb.y, rb.width, rb.height);
		blob.mask = m;
		blob.inside = in;
		blob.outside = out_level;
		Square sq;
		sq.centroid = {blob.box.x + mo.m10 / mo.m00, blob.box.y + mo.m01 / mo.m00};
		sq.area = best_area;
		out.squares.push_back(sq);
		out.blobs.push_back(std::move(blob));
	}
	return out;
}

Pass extract(const cv::Mat &intensity, const SquareParams &params, int window, double side, double max_area)
{
	cv::Mat labels;
	std::vector<Component> comps = components(local_mean_mask(intensity, window), params.min_area_px, &labels);
	return extract(intensity, params, labels, comps, side, max_area);
}

double median_square_area(const std::vector<Square> &squares, double lo, double hi)
{
	std::vector<float> a;
	for (const Square &s : squares)
		if (s.area >= lo && s.area <= hi)
			a.push_back(float(s.area));
	return median_of(a);
}

} // namespace

int first_window_px(const SquareParams &params, cv::Size frame)
{
	return params.first_window_px > 0 ? params.first_window_px : std::max(15, std::min(frame.width, frame.height) / 20);
}

Status find_squares(const cv::Mat &intensity, const SquareParams &params,
		    std::vector<Square> *ret_squares, std::vector<SquareBlob> *ret_blobs)
{
	if (intensity.empty() || intensity.type() != CV_32F)
		return Status::error(EINVAL, "find_squares needs a CV_32F intensity image");
	const int window = first_window_px(params, intensity.size());
	cv::Mat labels;
	cv::Mat mask = local_mean_mask(intensity, window);
	std::vector<Component> comps = components(mask, params.min_area_px, &labels);
	if (comps.empty()) {
		ret_squares->clear();
		ret_blobs->clear();
		return {};
	}
	double side = std::sqrt(median_area(comps));
	if (params.window_sides > 0) {
		int w2 = int(std::lround(params.window_sides * side));
		if (w2 > 0 && (w2 > window * 1.3 || w2 < window / 1.3)) {
			mask = local_mean_mask(intensity, w2);
			comps = components(mask, params.min_area_px, &labels);
			if (!comps.empty())
				side = std::sqrt(median_area(comps));
		}
	}
	Pass main = extract(intensity, params, labels, comps, side, params.max_area_ratio * side * side * 1.2);
	// Area filter against the median of what survived.
	double med = median_square_area(main.squares, 0, INFINITY);
	const double lo = params.min_area_ratio * med, hi = params.max_area_ratio * med;
	std::vector<Square> keep_sq;
	std::vector<SquareBlob> keep_blob;
	std::vector<float> small, big(main.skipped_areas);
	for (size_t k = 0; k < main.squares.size(); k++) {
		const double a = main.squares[k].area;
		if (a >= lo && a <= hi) {
			keep_sq.push_back(main.squares[k]);
			keep_blob.push_back(std::move(main.blobs[k]));
		} else {
			(a < lo ? small : big).push_back(float(a));
		}
	}
	// A second square size in the view: projectors of different pitch (6-20 mm on the face in
	// random booths), or one much nearer. Judged against the first size's median its squares
	// are refused, and a window of three of the first size's sides breaks a square three times
	// as large into a ring; so each other size with enough blobs gets its own pass, its window
	// and area range set by its own median, and adds the squares no kept square overlaps.
	for (std::vector<float> *cls : {&big, &small}) {
		if (params.min_class_squares <= 0 || cls->size() < size_t(params.min_class_squares) || !(med > 0))
			continue;
		const double cside = std::sqrt(median_of(*cls));
		const int cwin = std::max(3, int(std::lround(params.window_sides * cside)));
		Pass other = extract(intensity, params, cwin, cside, params.max_area_ratio * cside * cside * 1.2);
		// The class's own median, over its squares outside the first size's range.
		double cmed = cls == &big ? median_square_area(other.squares, hi, INFINITY)
					  : median_square_area(other.squares, 0, lo);
		if (!(cmed > 0))
			continue;
		const double clo = std::max(params.min_area_ratio * cmed, cls == &big ? hi : 0.0);
		const double chi = std::min(params.max_area_ratio * cmed, cls == &big ? INFINITY : lo);
		std::vector<Square> add_sq;
		std::vector<SquareBlob> add_blob;
		for (size_t k = 0; k < other.squares.size(); k++) {
			const Square &s = other.squares[k];
			if (s.area < clo || s.area > chi)
				continue;
			const cv::Rect &b = other.blobs[k].box;
			bool overlaps = false;
			for (size_t j = 0; j < keep_sq.size() && !overlaps; j++)
				overlaps = keep_blob[j].box.contains(cv::Point(int(s.centroid.x), int(s.centroid.y))) ||
					   b.contains(cv::Point(int(keep_sq[j].centroid.x), int(keep_sq[j].centroid.y)));
			if (overlaps)
				continue;
			add_sq.push_back(s);
			add_blob.push_back(std::move(other.blobs[k]));
		}
		// Too few to be a size of the pattern: specks, merged pairs.
		if (add_sq.size() < size_t(params.min_class_squares))
			continue;
		for (size_t k = 0; k < add_sq.size(); k++) {
			keep_sq.push_back(add_sq[k]);
			keep_blob.push_back(std::move(add_blob[k]));
		}
	}
	*ret_squares = std::move(keep_sq);
	*ret_blobs = std::move(keep_blob);
	return {};
}

Status add_letter_squares(const std::vector<cv::Mat> &planes, cv::Point origin,
			  const SquareParams &squares_params, const CornerParams &corner_params,
			  const LetterPlaneParams &params, std::vector<Square> *squares,
			  std::vector<SquareBlob> *blobs)
{
	if (squares->size() != blobs->size())
		return Status::error(EINVAL, "add_letter_squares: one blob per square expected");
	if (planes.empty())
		return Status::error(EINVAL, "add_letter_squares needs planes");
	for (const cv::Mat &p : planes)
		if (p.empty() || p.type() != CV_32F || p.size() != planes[0].size())
			return Status::error(EINVAL, "add_letter_squares needs CV_32F planes of one size");
	const size_t n_before = squares->size();
	const cv::Rect area(origin, planes[0].size());
	std::vector<char> blended(n_before, 0);
	std::vector<Square> add_sq;
	std::vector<SquareBlob> add_blob;
	// The squares read whole (corners and a letter) are dark in the planes: a plane finds at most
	// a piece of one there (the skin's tint shifts a letter's colour under the lips, the brows),
	// and most of the planes' blobs, the cost of find_squares, go with them.
	cv::Mat whole(planes[0].size(), CV_8U, cv::Scalar(0));
	for (size_t j = 0; j < n_before; j++) {
		const SquareBlob &b = (*blobs)[j];
		const cv::Rect in = b.box & area;
		if ((*squares)[j].has_corners && (*squares)[j].letter >= 0 && in.area() > 0)
			whole(in - origin).setTo(255, b.mask(in - b.box.tl()));
	}
	cv::dilate(whole, whole, cv::Mat(), cv::Point(-1, -1), 2);
	std::vector<cv::Mat> smooth(planes.size()), search(planes.size());
	for (size_t l = 0; l < planes.size(); l++) {
		cv::GaussianBlur(planes[l], smooth[l], cv::Size(5, 5), 1.0, 1.0, cv::BORDER_REPLICATE);
		search[l] = smooth[l].clone();
		search[l].setTo(0, whole);
	}
	const cv::Point2d shift(origin);
	for (size_t l = 0; l < planes.size(); l++) {
		std::vector<Square> sq;
		std::vector<SquareBlob> bl;
		Status st = find_squares(search[l], squares_params, &sq, &bl);
		if (!st.ok())
			return st;
		// A plane square the intensity stage has already, or that is not mostly this letter's
		// light (what a colour error leaks into the plane), is dropped before the corners.
		std::vector<Square> fresh;
		std::vector<SquareBlob> fresh_blobs;
		std::vector<cv::Point> centre; // area centroids, image pixels (detect_corners moves the centroid)
		for (size_t k = 0; k < sq.size(); k++) {
			const cv::Point c(int(sq[k].centroid.x + shift.x), int(sq[k].centroid.y + shift.y));
			const cv::Rect box = bl[k].box + origin;
			bool known = false;
			for (size_t j = 0; j < n_before && !known; j++) {
				const Square &o = (*squares)[j];
				const double ratio = std::max(o.area, sq[k].area) / std::max(1.0, std::min(o.area, sq[k].area));
				known = ratio < params.same_area_ratio && (*blobs)[j].box.contains(c) &&
					box.contains(cv::Point(int(o.centroid.x), int(o.centroid.y)));
			}
			if (known)
				continue;
			// Its own light against the strongest other letter's inside it (the other copy's
			// squares overlap part of it).
			const SquareBlob &b = bl[k];
			const double own = cv::mean(smooth[l](b.box), b.mask)[0];
			double other = 0;
			for (size_t m = 0; m < planes.size(); m++)
				if (m != l)
					other = std::max(other, cv::mean(smooth[m](b.box), b.mask)[0]);
			const double confidence = own > 0 ? std::clamp(1 - other / own, 0.0, 1.0) : 0.0;
			if (confidence < params.min_confidence)
				continue;
			sq[k].letter = int(l);
			sq[k].confidence = float(confidence);
			fresh.push_back(sq[k]);
			centre.push_back(c);
			fresh_blobs.push_back(std::move(bl[k]));
		}
		detect_corners(smooth[l], fresh_blobs, corner_params, &fresh);
		for (size_t k = 0; k < fresh.size(); k++) {
			// Without corners a plane's blob is as likely a colour fringe along another
			// square's edge (blur, demosaicing) as a square: it would only steal grid links.
			if (!fresh[k].has_corners)
				continue;
			for (size_t j = 0; j < n_before; j++) {
				const SquareBlob &o = (*blobs)[j];
				if (o.box.contains(centre[k]) && o.mask.at<uchar>(centre[k] - o.box.tl()))
					blended[j] = 1;
			}
			Square q = fresh[k];
			q.centroid += shift;
			for (cv::Point2d &p : q.corners)
				p += shift;
			SquareBlob b = std::move(fresh_blobs[k]);
			b.box += origin;
			add_sq.push_back(q);
			add_blob.push_back(std::move(b));
		}
	}
	std::vector<Square> out_sq;
	std::vector<SquareBlob> out_blob;
	for (size_t j = 0; j < n_before; j++)
		if (!blended[j]) {
			out_sq.push_back((*squares)[j]);
			out_blob.push_back(std::move((*blobs)[j]));
		}
	for (size_t k = 0; k < add_sq.size(); k++) {
		out_sq.push_back(add_sq[k]);
		out_blob.push_back(std::move(add_blob[k]));
	}
	*squares = std::move(out_sq);
	*blobs = std::move(out_blob);
	return {};
}

} // namespace facescan::recon
