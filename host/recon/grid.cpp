// Stage 2: grid topology. Each square's own four corners give a homography from the image to the
// slide around it (units of one pitch); a neighbour's centre must land one pitch up, left, right
// or down there. That holds on a curved, foreshortened face as long as the surface is smooth over
// one pitch, which a fixed image-space search radius or direction would not.
#include "recon/image_stages.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <unordered_map>

namespace facescan::recon {

namespace {

// Unit offsets (dx, dy) on the slide of the up, left, right, down neighbour.
constexpr int kDx[4] = {0, -1, 1, 0};
constexpr int kDy[4] = {-1, 0, 0, 1};

int opposite(int dir)
{
	return 3 - dir;
}

} // namespace

void link_grid(double gap_fraction, const GridParams &params, std::vector<Square> *squares)
{
	std::vector<Square> &sq = *squares;
	const double s = 1.0 - gap_fraction;
	double cell = 0;
	for (const Square &q : sq)
		cell = std::max(cell, std::sqrt(q.area) / s);
	for (Square &q : sq)
		q.neighbours = {{-1, -1, -1, -1}};
	if (sq.empty() || cell <= 0)
		return;
	// Spatial hash of centroids, cells of one (largest) pitch.
	auto key_of = [](int gx, int gy) { return int64_t(uint64_t(uint32_t(gy)) << 32 | uint32_t(gx)); };
	auto key = [cell, key_of](const cv::Point2d &p) {
		return key_of(int(std::floor(p.x / cell)), int(std::floor(p.y / cell)));
	};
	std::unordered_map<int64_t, std::vector<int>> hash;
	for (size_t i = 0; i < sq.size(); i++)
		hash[key(sq[i].centroid)].push_back(int(i));

	std::vector<std::array<int, 4>> found(sq.size(), {{-1, -1, -1, -1}});
	const double cos_limit = std::cos(params.max_angle_deg * M_PI / 180.0);
	const cv::Point2f dst[4] = {{0, 0}, {float(s), 0}, {float(s), float(s)}, {0, float(s)}};
	for (size_t i = 0; i < sq.size(); i++) {
		if (!sq[i].has_corners)
			continue;
		cv::Point2f src[4];
		for (int k = 0; k < 4; k++)
			src[k] = cv::Point2f(sq[i].corners[size_t(k)]);
		cv::Matx33d H = cv::getPerspectiveTransform(src, dst);
		// H is defined up to scale, its sign included: points on the square's side of the
		// horizon share the sign of the square's own centre.
		const double own_w = (H * cv::Vec3d(sq[i].centroid.x, sq[i].centroid.y, 1))[2];
		std::array<double, 4> best{{1e9, 1e9, 1e9, 1e9}};
		int cx = int(std::floor(sq[i].centroid.x / cell)), cy = int(std::floor(sq[i].centroid.y / cell));
		for (int gy = cy - 2; gy <= cy + 2; gy++)
			for (int gx = cx - 2; gx <= cx + 2; gx++) {
				auto it = hash.find(key_of(gx, gy));
				if (it == hash.end())
					continue;
				for (int j : it->second) {
					if (size_t(j) == i)
						continue;
					const cv::Point2d &p = sq[size_t(j)].centroid;
					cv::Vec3d h = H * cv::Vec3d(p.x, p.y, 1);
					if (h[2] * own_w <= 0)
						continue;
					double u = h[0] / h[2] - s / 2, v = h[1] / h[2] - s / 2;
					double dist = std::hypot(u, v);
					if (dist < params.min_pitches || dist > params.max_pitches)
						continue;
					for (int d = 0; d < 4; d++) {
						double cosang = (u * kDx[d] + v * kDy[d]) / dist;
						if (cosang >= cos_limit && dist < best[size_t(d)]) {
							best[size_t(d)] = dist;
							found[i][size_t(d)] = j;
						}
					}
				}
			}
	}
	// Keep links both ends agree on (or that the far end, without corners, cannot contradict).
	for (size_t i = 0; i < sq.size(); i++)
		for (int d = 0; d < 4; d++) {
			int j = found[i][size_t(d)];
			if (j < 0)
				continue;
			if (sq[size_t(j)].has_corners && found[size_t(j)][size_t(opposite(d))] != int(i))
				continue;
			sq[i].neighbours[size_t(d)] = j;
			if (!sq[size_t(j)].has_corners)
				sq[size_t(j)].neighbours[size_t(opposite(d))] = int(i);
		}
	// A corner-less square linked from two sides in the same direction is ambiguous: unlink.
	for (size_t i = 0; i < sq.size(); i++) {
		if (sq[i].has_corners)
			continue;
		for (int d = 0; d < 4; d++) {
			int j = sq[i].neighbours[size_t(d)];
			if (j >= 0 && sq[size_t(j)].neighbours[size_t(opposite(d))] != int(i))
				sq[i].neighbours[size_t(d)] = -1;
		}
	}
}

void check_grid_shapes(const GridParams &params, std::vector<Square> *squares)
{
	std::vector<Square> &sq = *squares;
	// Mean length of the horizontal (TL-TR, BL-BR) and vertical (TL-BL, TR-BR) sides.
	auto sides = [](const Square &q, int vertical) {
		const auto &c = q.corners;
		return vertical ? 0.5 * (cv::norm(c[3] - c[0]) + cv::norm(c[2] - c[1]))
				: 0.5 * (cv::norm(c[1] - c[0]) + cv::norm(c[2] - c[3]));
	};
	std::vector<char> irregular(sq.size(), 0);
	for (size_t i = 0; i < sq.size(); i++) {
		if (!sq[i].has_corners)
			continue;
		for (int vertical = 0; vertical < 2; vertical++) {
			// Vertical sides from the up (0) and down (3) neighbours; horizontal from left (1), right (2).
			int a = sq[i].neighbours[vertical ? 0 : 1], b = sq[i].neighbours[vertical ? 3 : 2];
			double sum = 0;
			int n = 0;
			for (int j : {a, b})
				if (j >= 0 && sq[size_t(j)].has_corners) {
					sum += sides(sq[size_t(j)], vertical);
					n++;
				}
			if (!n)
				continue;
			double ratio = sides(sq[i], vertical) / (sum / n);
			double tol = n == 2 ? params.shape_tolerance : params.single_tolerance;
			if (std::abs(ratio - 1) > tol)
				irregular[i] = 1;
		}
	}
	for (size_t i = 0; i < sq.size(); i++)
		if (irregular[i]) {
			sq[i].irregular = true;
			sq[i].has_corners = false;
		}
}

} // namespace facescan::recon
