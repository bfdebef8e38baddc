// Stage 1a: the paper's HSI colour model (Gonzalez & Woods), all planes on 0..255.
#include "recon/image_stages.hpp"

#include <algorithm>
#include <cmath>

namespace facescan::recon {

cv::Vec3d hsi_of_bgr(const cv::Vec3d &bgr)
{
	double b = bgr[0], g = bgr[1], r = bgr[2];
	double sum = b + g + r;
	double i = sum / 3;
	if (sum <= 0)
		return {0, 0, 0};
	double s = 1 - 3 * std::min({b, g, r}) / sum;
	double num = 0.5 * ((r - g) + (r - b));
	double den = std::sqrt((r - g) * (r - g) + (r - b) * (g - b));
	double h = 0;
	if (den > 1e-9 && s > 1e-9) {
		double theta = std::acos(std::clamp(num / den, -1.0, 1.0)) * 180.0 / M_PI;
		h = b > g ? 360.0 - theta : theta;
	}
	return {h * 255.0 / 360.0, s * 255.0, i};
}

Status bgr_to_hsi(const cv::Mat &bgr, HsiImage *ret_hsi)
{
	if (bgr.empty() || bgr.type() != CV_8UC3)
		return Status::error(EINVAL, "HSI conversion needs an 8-bit 3-channel image");
	HsiImage out;
	out.h.create(bgr.size(), CV_32F);
	out.s.create(bgr.size(), CV_32F);
	out.i.create(bgr.size(), CV_32F);
	for (int y = 0; y < bgr.rows; y++) {
		const cv::Vec3b *p = bgr.ptr<cv::Vec3b>(y);
		float *h = out.h.ptr<float>(y), *s = out.s.ptr<float>(y), *i = out.i.ptr<float>(y);
		for (int x = 0; x < bgr.cols; x++) {
			cv::Vec3d v = hsi_of_bgr(cv::Vec3d(p[x][0], p[x][1], p[x][2]));
			h[x] = float(v[0]);
			s[x] = float(v[1]);
			i[x] = float(v[2]);
		}
	}
	*ret_hsi = std::move(out);
	return {};
}

std::array<float, 256> linear_table(double gamma)
{
	std::array<float, 256> t;
	for (int v = 0; v < 256; v++)
		t[size_t(v)] = float(255.0 * std::pow(v / 255.0, gamma));
	return t;
}

Status bgr_to_intensity(const cv::Mat &bgr, cv::Mat *ret_intensity, double gamma)
{
	if (bgr.empty() || bgr.type() != CV_8UC3)
		return Status::error(EINVAL, "intensity needs an 8-bit 3-channel image");
	if (!(gamma > 0))
		return Status::error(EINVAL, "intensity: gamma must be positive");
	const std::array<float, 256> lin = linear_table(gamma);
	cv::Mat out(bgr.size(), CV_32F);
	for (int y = 0; y < bgr.rows; y++) {
		const uchar *p = bgr.ptr<uchar>(y);
		float *o = out.ptr<float>(y);
		for (int x = 0; x < bgr.cols; x++, p += 3)
			o[x] = (lin[p[0]] + lin[p[1]] + lin[p[2]]) * (1.0f / 3.0f);
	}
	*ret_intensity = std::move(out);
	return {};
}

Status letter_planes(const cv::Mat &bgr, double gamma, const std::vector<cv::Vec3d> &colours,
		     double min_share, std::vector<cv::Mat> *ret_planes)
{
	if (bgr.empty() || bgr.type() != CV_8UC3)
		return Status::error(EINVAL, "letter planes need an 8-bit 3-channel image");
	if (!(gamma > 0))
		return Status::error(EINVAL, "letter planes: gamma must be positive");
	if (colours.size() != 3)
		return Status::error(EINVAL, "letter planes: exactly 3 letter colours are unmixed");
	// Columns: the letters' colours; a pixel's light = mix · (light of each letter).
	cv::Matx33d mix;
	for (int l = 0; l < 3; l++)
		for (int c = 0; c < 3; c++)
			mix(c, l) = colours[size_t(l)][c];
	if (std::abs(cv::determinant(mix)) < 1e-4)
		return Status::error(EINVAL, "letter planes: the letter colours are not independent");
	const cv::Matx33d unmix = mix.inv();
	const std::array<float, 256> lin = linear_table(gamma);
	// unmix · linear colour as three table look-ups per plane.
	std::array<std::array<std::array<float, 256>, 3>, 3> term;
	for (size_t l = 0; l < 3; l++)
		for (size_t c = 0; c < 3; c++)
			for (size_t v = 0; v < 256; v++)
				term[l][c][v] = float(unmix(int(l), int(c)) * lin[v]);
	const float share = float(min_share);
	std::vector<cv::Mat> planes(3);
	for (cv::Mat &p : planes)
		p.create(bgr.size(), CV_32F);
	for (int y = 0; y < bgr.rows; y++) {
		const uchar *p = bgr.ptr<uchar>(y);
		float *o[3] = {planes[0].ptr<float>(y), planes[1].ptr<float>(y), planes[2].ptr<float>(y)};
		for (int x = 0; x < bgr.cols; x++, p += 3) {
			float v[3];
			for (size_t l = 0; l < 3; l++)
				v[l] = term[l][0][p[0]] + term[l][1][p[1]] + term[l][2][p[2]];
			const float top = std::max({v[0], v[1], v[2]});
			for (int l = 0; l < 3; l++)
				o[l][x] = v[l] > 0 && v[l] >= share * top ? v[l] : 0.0f;
		}
	}
	*ret_planes = std::move(planes);
	return {};
}

} // namespace facescan::recon
