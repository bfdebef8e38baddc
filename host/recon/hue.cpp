// Stage 1c: code letters from hue, adapted to each capture.
//
// The observed colour of a square is the projector's colour times the skin's reflectance plus
// ambient light. The ambient part is removed by subtracting the gap colour around the square; the
// reflectance tint by white-balancing with the mean colour of all squares (the letters are about
// equally frequent, so their mean is grey on the slide). What is left is clustered on the hue
// circle, seeded at the slide's letter hues, so the clusters follow this capture's real hues.
#include "recon/image_stages.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace facescan::recon {

namespace {

double hue_deg(const cv::Vec3d &bgr)
{
	double b = bgr[0], g = bgr[1], r = bgr[2];
	double a = std::atan2(std::sqrt(3.0) * (g - b), 2 * r - g - b) * 180.0 / M_PI;
	return a < 0 ? a + 360.0 : a;
}

double chroma_ratio(const cv::Vec3d &bgr)
{
	double b = bgr[0], g = bgr[1], r = bgr[2];
	double sum = r + g + b;
	if (sum <= 1e-9)
		return 0;
	double x = 2 * r - g - b, y = std::sqrt(3.0) * (g - b);
	return 0.5 * std::hypot(x, y) / sum;
}

double angle_diff(double a, double b)
{
	double d = std::fmod(std::abs(a - b), 360.0);
	return d > 180 ? 360 - d : d;
}

double channel_median(std::vector<float> &v)
{
	if (v.empty())
		return 0;
	auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
	std::nth_element(v.begin(), mid, v.end());
	return *mid;
}

struct SquareColour {
	bool ok = false;
	cv::Vec3d mean;			  // inside minus gap, B G R
	std::vector<cv::Vec3f> pixels;	  // inside minus gap
};

SquareColour square_colour(const cv::Mat &bgr, const SquareBlob &b, const std::array<float, 256> &lin)
{
	SquareColour out;
	double side = std::sqrt(std::max(1.0, double(cv::countNonZero(b.mask))));
	int grow = std::max(2, int(std::lround(0.15 * side)));
	cv::Rect frame(0, 0, bgr.cols, bgr.rows);
	cv::Rect big(b.box.x - grow, b.box.y - grow, b.box.width + 2 * grow, b.box.height + 2 * grow);
	big &= frame;
	cv::Mat m(big.size(), CV_8U, cv::Scalar(0));
	b.mask.copyTo(m(cv::Rect(b.box.x - big.x, b.box.y - big.y, b.box.width, b.box.height)));
	cv::Mat inner, outer;
	int shrink = side >= 20 ? 2 : (side >= 8 ? 1 : 0);
	if (shrink)
		cv::erode(m, inner, cv::Mat(), cv::Point(-1, -1), shrink);
	else
		inner = m;
	cv::dilate(m, outer, cv::Mat(), cv::Point(-1, -1), 1);
	std::array<std::vector<float>, 3> ring;
	cv::Mat roi = bgr(big);
	for (int y = 0; y < big.height; y++) {
		const cv::Vec3b *p = roi.ptr<cv::Vec3b>(y);
		const uchar *o = outer.ptr<uchar>(y);
		for (int x = 0; x < big.width; x++)
			if (!o[x])
				for (size_t c = 0; c < 3; c++)
					ring[c].push_back(lin[p[x][int(c)]]);
	}
	if (ring[0].size() < 4)
		return out;
	cv::Vec3d gap(channel_median(ring[0]), channel_median(ring[1]), channel_median(ring[2]));
	cv::Vec3d sum(0, 0, 0);
	for (int y = 0; y < big.height; y++) {
		const cv::Vec3b *p = roi.ptr<cv::Vec3b>(y);
		const uchar *in = inner.ptr<uchar>(y);
		for (int x = 0; x < big.width; x++)
			if (in[x]) {
				cv::Vec3f v(float(lin[p[x][0]] - gap[0]), float(lin[p[x][1]] - gap[1]),
					    float(lin[p[x][2]] - gap[2]));
				out.pixels.push_back(v);
				sum += cv::Vec3d(v[0], v[1], v[2]);
			}
	}
	if (out.pixels.empty())
		return out;
	out.mean = sum * (1.0 / double(out.pixels.size()));
	for (int c = 0; c < 3; c++)
		out.mean[c] = std::max(0.0, out.mean[c]);
	out.ok = out.mean[0] + out.mean[1] + out.mean[2] > 1;
	return out;
}

} // namespace

Status classify_letters(const cv::Mat &bgr, const std::vector<SquareBlob> &blobs,
			const Pattern &pattern, const HueParams &params, std::vector<Square> *squares)
{
	if (bgr.empty() || bgr.type() != CV_8UC3)
		return Status::error(EINVAL, "classify_letters needs an 8-bit BGR image");
	if (blobs.size() != squares->size())
		return Status::error(EINVAL, "classify_letters: one blob per square expected");
	const int letters = pattern.matrix.letters();
	if (letters < 2)
		return Status::error(EINVAL, "classify_letters: the pattern has fewer than 2 letters");
	if (!(params.gamma > 0))
		return Status::error(EINVAL, "classify_letters: gamma must be positive");
	const std::array<float, 256> lin = linear_table(params.gamma);
	std::vector<SquareColour> colours(blobs.size());
	cv::Vec3d total(0, 0, 0);
	for (size_t i = 0; i < blobs.size(); i++) {
		colours[i] = square_colour(bgr, blobs[i], lin);
		if (colours[i].ok) {
			const cv::Vec3d &m = colours[i].mean;
			total += m * (1.0 / (m[0] + m[1] + m[2]));
		}
		(*squares)[i].letter = -1;
		(*squares)[i].confidence = 0;
	}
	// White balance: the reflectance tint of the whole capture, from all squares' chromaticity.
	cv::Vec3d gain(1, 1, 1);
	double tsum = total[0] + total[1] + total[2];
	if (tsum > 0)
		for (int c = 0; c < 3; c++)
			gain[c] = total[c] > 1e-6 * tsum ? tsum / (3 * total[c]) : 1;

	std::vector<double> hue(blobs.size(), -1);
	for (size_t i = 0; i < blobs.size(); i++) {
		if (!colours[i].ok)
			continue;
		cv::Vec3d m = colours[i].mean.mul(gain);
		if (chroma_ratio(m) < params.min_saturation)
			continue;
		// Circular spread of the per-pixel hues: mixed colours (projector seams) spread wide.
		double sx = 0, sy = 0, ref = hue_deg(m);
		for (const cv::Vec3f &p : colours[i].pixels) {
			cv::Vec3d q(p[0] * gain[0], p[1] * gain[1], p[2] * gain[2]);
			double a = (hue_deg(q) - ref) * M_PI / 180.0;
			sx += std::cos(a);
			sy += std::sin(a);
		}
		double rlen = std::hypot(sx, sy) / double(colours[i].pixels.size());
		double spread = std::sqrt(-2 * std::log(std::clamp(rlen, 1e-9, 1.0))) * 180.0 / M_PI;
		if (spread > params.max_hue_spread_deg)
			continue;
		hue[i] = ref;
	}
	// k-means on the hue circle, seeded at the slide's hues.
	std::vector<double> centre(static_cast<size_t>(letters));
	for (int l = 0; l < letters; l++)
		centre[size_t(l)] = letter_hue(l, letters) * 360.0 / 255.0;
	std::vector<int> assign(blobs.size(), -1);
	for (int it = 0; it < params.iterations; it++) {
		std::vector<double> cx(static_cast<size_t>(letters), 0.0), cy(static_cast<size_t>(letters), 0.0);
		std::vector<int> cn(static_cast<size_t>(letters), 0);
		for (size_t i = 0; i < hue.size(); i++) {
			if (hue[i] < 0)
				continue;
			int best = 0;
			for (int l = 1; l < letters; l++)
				if (angle_diff(hue[i], centre[size_t(l)]) < angle_diff(hue[i], centre[size_t(best)]))
					best = l;
			assign[i] = best;
			cx[size_t(best)] += std::cos(hue[i] * M_PI / 180);
			cy[size_t(best)] += std::sin(hue[i] * M_PI / 180);
			cn[size_t(best)]++;
		}
		for (int l = 0; l < letters; l++)
			if (cn[size_t(l)]) {
				double a = std::atan2(cy[size_t(l)], cx[size_t(l)]) * 180.0 / M_PI;
				centre[size_t(l)] = a < 0 ? a + 360 : a;
			}
	}
	for (size_t i = 0; i < hue.size(); i++) {
		if (hue[i] < 0)
			continue;
		double d1 = 1e9, d2 = 1e9;
		int best = -1;
		for (int l = 0; l < letters; l++) {
			double d = angle_diff(hue[i], centre[size_t(l)]);
			if (d < d1) {
				d2 = d1;
				d1 = d;
				best = l;
			} else if (d < d2) {
				d2 = d;
			}
		}
		double conf = (d2 - d1) / std::max(1e-9, d2 + d1);
		Square &sq = (*squares)[i];
		sq.confidence = float(conf);
		sq.letter = conf >= params.min_confidence ? best : -1;
	}
	return {};
}

Status letter_colours(const cv::Mat &bgr, const std::vector<SquareBlob> &blobs,
		      const std::vector<Square> &squares, int letters, double gamma, int min_squares,
		      std::vector<cv::Vec3d> *ret_colours)
{
	if (bgr.empty() || bgr.type() != CV_8UC3)
		return Status::error(EINVAL, "letter_colours needs an 8-bit BGR image");
	if (blobs.size() != squares.size() || letters < 1 || !(gamma > 0))
		return Status::error(EINVAL, "letter_colours: one blob per square, letters and gamma > 0");
	const std::array<float, 256> lin = linear_table(gamma);
	std::vector<cv::Vec3d> sum(size_t(letters), cv::Vec3d(0, 0, 0));
	std::vector<int> count(size_t(letters), 0);
	for (size_t i = 0; i < squares.size(); i++) {
		const int l = squares[i].letter;
		if (l < 0 || l >= letters)
			continue;
		const SquareColour c = square_colour(bgr, blobs[i], lin);
		if (!c.ok)
			continue;
		// Unit sum: a bright square weighs as much as a dim one.
		sum[size_t(l)] += c.mean * (1.0 / (c.mean[0] + c.mean[1] + c.mean[2]));
		count[size_t(l)]++;
	}
	for (int l = 0; l < letters; l++) {
		if (count[size_t(l)] < std::max(1, min_squares))
			return Status::error(ENODATA, "letter_colours: too few squares of letter " + std::to_string(l));
		sum[size_t(l)] *= 1.0 / count[size_t(l)];
	}
	*ret_colours = std::move(sum);
	return {};
}

} // namespace facescan::recon
