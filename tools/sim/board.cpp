// Calibration-target images by ray casting (see board.hpp).
#include "sim/board.hpp"

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace facescan::sim {

namespace {

// Normalised ray directions (x/z, y/z) of the sample points of every pixel, `ss` x `ss` samples
// per pixel at their centres: a CV_32FC2 image of (width * ss) x (height * ss).
cv::Mat pixel_rays(const CameraModel &cam, int ss)
{
	const int w = cam.size.width * ss, h = cam.size.height * ss;
	cv::Mat pts(h * w, 1, CV_64FC2);
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++)
			pts.at<cv::Vec2d>(y * w + x) =
				cv::Vec2d((x + 0.5) / ss - 0.5, (y + 0.5) / ss - 0.5);
	cv::Mat rays;
	// Tight criteria: the images must match cv::projectPoints' model to far below a pixel.
	cv::undistortPoints(pts, rays, cam.K, cam.dist, cv::noArray(), cv::noArray(),
			    cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
	cv::Mat out;
	rays.reshape(2, h).convertTo(out, CV_32FC2);
	return out;
}

// Where each ray meets the board plane, in board mm (CV_64FC2); NaN where the ray misses the
// board's front (parallel, behind the camera, or the back side of the board).
cv::Mat board_hits(const CameraModel &cam, const cv::Mat &rays, const BoardPose &pose)
{
	const cv::Matx33d M = pose.R.t() * cam.R.t(); // camera direction → board direction
	const cv::Vec3d C = pose.R.t() * (cam.centre() - pose.t); // camera centre in the board frame
	cv::Mat hits(rays.size(), CV_64FC2);
	const double nan = std::nan("");
	for (int y = 0; y < rays.rows; y++) {
		const cv::Vec2f *r = rays.ptr<cv::Vec2f>(y);
		cv::Vec2d *o = hits.ptr<cv::Vec2d>(y);
		for (int x = 0; x < rays.cols; x++) {
			const cv::Vec3d d = M * cv::Vec3d(r[x][0], r[x][1], 1.0);
			// Front side: the ray goes into the board (+z) from the camera in front (z < 0).
			if (d[2] <= 1e-12 || C[2] >= 0) {
				o[x] = cv::Vec2d(nan, nan);
				continue;
			}
			const double lambda = -C[2] / d[2];
			o[x] = cv::Vec2d(C[0] + lambda * d[0], C[1] + lambda * d[1]);
		}
	}
	return hits;
}

// Integral of the ±1 square wave of period 2s that is +1 on [0, s): a triangle wave.
double square_wave_integral(double x, double s)
{
	double m = std::fmod(x, 2 * s);
	if (m < 0)
		m += 2 * s;
	return m < s ? m : 2 * s - m;
}

// The square wave averaged over [x - w, x + w].
double filtered_wave(double x, double w, double s)
{
	if (w < 1e-9)
		return std::fmod(std::floor(x / s), 2.0) == 0 ? 1.0 : -1.0;
	return (square_wave_integral(x + w, s) - square_wave_integral(x - w, s)) / (2 * w);
}

// Fraction of [x - w, x + w] inside [lo, hi].
double coverage(double x, double w, double lo, double hi)
{
	w = std::max(w, 1e-9);
	const double a = std::max(x - w, lo), b = std::min(x + w, hi);
	return std::clamp((b - a) / (2 * w), 0.0, 1.0);
}

// Half the pixel footprint's extent in board x and y, from neighbouring hits.
cv::Vec2d footprint(const cv::Mat &hits, int x, int y)
{
	auto at = [&](int xx, int yy) {
		return hits.at<cv::Vec2d>(std::clamp(yy, 0, hits.rows - 1),
					  std::clamp(xx, 0, hits.cols - 1));
	};
	const cv::Vec2d du = (at(x + 1, y) - at(x - 1, y)) * 0.5;
	const cv::Vec2d dv = (at(x, y + 1) - at(x, y - 1)) * 0.5;
	cv::Vec2d w(0.5 * (std::abs(du[0]) + std::abs(dv[0])), 0.5 * (std::abs(du[1]) + std::abs(dv[1])));
	if (!std::isfinite(w[0]) || !std::isfinite(w[1]))
		w = cv::Vec2d(0, 0);
	return w;
}

// The chessboard, box-filtered over each pixel's footprint (exact for the checker's product of
// two square waves over an axis-aligned box).
cv::Mat shade_chessboard(const cv::Mat &hits, const calib::BoardSpec &board, const BoardRenderParams &p)
{
	const double s = board.square_mm;
	const double x0 = -s, x1 = board.cols * s, y0 = -s, y1 = board.rows * s; // the squares
	const double m = p.margin_squares * s;
	const double mid = 0.5 * (p.white + p.black), amp = 0.5 * (p.white - p.black);
	cv::Mat img(hits.size(), CV_32F);
	for (int y = 0; y < hits.rows; y++)
		for (int x = 0; x < hits.cols; x++) {
			const cv::Vec2d h = hits.at<cv::Vec2d>(y, x);
			if (!std::isfinite(h[0])) {
				img.at<float>(y, x) = float(p.background);
				continue;
			}
			const cv::Vec2d w = footprint(hits, x, y);
			// Squares counted from inner corner 0: the one at [0,s)x[0,s) is black.
			const double checker = mid - amp * filtered_wave(h[0], w[0], s) *
							     filtered_wave(h[1], w[1], s);
			const double in_sq = coverage(h[0], w[0], x0, x1) * coverage(h[1], w[1], y0, y1);
			const double in_board = coverage(h[0], w[0], x0 - m, x1 + m) *
						coverage(h[1], w[1], y0 - m, y1 + m);
			const double v = in_sq * checker + (in_board - in_sq) * p.white +
					 (1 - in_board) * p.background;
			img.at<float>(y, x) = float(v);
		}
	return img;
}

// The ChArUco board: OpenCV draws it into a fine texture, which is sampled ss x ss per pixel.
cv::Mat shade_charuco(const cv::Mat &hits, int ss, const calib::BoardSpec &board, const BoardRenderParams &p)
{
	const double ppm = 12; // texture pixels per mm
	const cv::Ptr<cv::aruco::Dictionary> dict = cv::aruco::getPredefinedDictionary(board.dictionary);
	const cv::Ptr<cv::aruco::CharucoBoard> cb = cv::aruco::CharucoBoard::create(
		board.cols + 1, board.rows + 1, float(board.square_mm), float(board.marker_mm), dict);
	const cv::Size tex_size(int(std::lround((board.cols + 1) * board.square_mm * ppm)),
				int(std::lround((board.rows + 1) * board.square_mm * ppm)));
	cv::Mat tex8;
	cb->draw(tex_size, tex8, 0, 1);
	cv::Mat tex;
	tex8.convertTo(tex, CV_32F, (p.white - p.black) / 255.0, p.black);
	const double s = board.square_mm, m = p.margin_squares * s;
	const cv::Point3f origin = cb->chessboardCorners[0]; // corner 0 from the outer corner
	cv::Mat fine(hits.size(), CV_32F);
	for (int y = 0; y < hits.rows; y++)
		for (int x = 0; x < hits.cols; x++) {
			const cv::Vec2d h = hits.at<cv::Vec2d>(y, x);
			float v = float(p.background);
			if (std::isfinite(h[0])) {
				const double bx = h[0] + origin.x, by = h[1] + origin.y; // from the outer corner
				const double W = (board.cols + 1) * s, H = (board.rows + 1) * s;
				if (bx >= 0 && by >= 0 && bx < W && by < H) {
					const float tx = float(bx * ppm - 0.5), ty = float(by * ppm - 0.5);
					const int ix = std::clamp(int(std::floor(tx)), 0, tex.cols - 2);
					const int iy = std::clamp(int(std::floor(ty)), 0, tex.rows - 2);
					const float fx = std::clamp(tx - float(ix), 0.f, 1.f);
					const float fy = std::clamp(ty - float(iy), 0.f, 1.f);
					const float *r0 = tex.ptr<float>(iy), *r1 = tex.ptr<float>(iy + 1);
					v = (1 - fy) * ((1 - fx) * r0[ix] + fx * r0[ix + 1]) +
					    fy * ((1 - fx) * r1[ix] + fx * r1[ix + 1]);
				} else if (bx >= -m && by >= -m && bx < W + m && by < H + m) {
					v = float(p.white);
				}
			}
			fine.at<float>(y, x) = v;
		}
	cv::Mat img;
	cv::resize(fine, img, cv::Size(hits.cols / ss, hits.rows / ss), 0, 0, cv::INTER_AREA);
	return img;
}

cv::Matx33d axis_rotation(const cv::Vec3d &axis, double deg)
{
	cv::Matx33d R;
	cv::Rodrigues(cv::Vec3d(axis * (deg * CV_PI / 180.0 / cv::norm(axis))), R);
	return R;
}

} // namespace

Status render_board(const CameraModel &camera, const calib::BoardSpec &board,
		    const BoardPose &pose, const BoardRenderParams &params, cv::Mat *ret_image)
{
	const BoardCamera cam(camera, board.type == calib::TargetType::Charuco ? 3 : 1);
	return cam.render(board, pose, params, ret_image);
}

BoardCamera::BoardCamera(const CameraModel &camera, int supersample)
	: camera_(camera), supersample_(std::clamp(supersample, 1, 8))
{
	if (camera_.size.width > 2 && camera_.size.height > 2) {
		rays_ = pixel_rays(camera_, 1);
		fine_rays_ = supersample_ > 1 ? pixel_rays(camera_, supersample_) : rays_;
	}
}

Status BoardCamera::render(const calib::BoardSpec &board, const BoardPose &pose,
			   const BoardRenderParams &params, cv::Mat *ret_image) const
{
	Status st = calib::validate_board(board);
	if (!st.ok())
		return st;
	if (camera_.size.width <= 2 || camera_.size.height <= 2)
		return Status::error(EINVAL, "render_board: the camera has no image size");
	const bool textured = board.type == calib::TargetType::Charuco;
	const cv::Mat hits = board_hits(camera_, textured ? fine_rays_ : rays_, pose);
	cv::Mat img = board.type == calib::TargetType::Chessboard
			      ? shade_chessboard(hits, board, params)
			      : shade_charuco(hits, supersample_, board, params);
	if (params.blur_sigma_px > 0)
		cv::GaussianBlur(img, img, cv::Size(0, 0), params.blur_sigma_px);
	if (params.noise_sigma > 0) {
		cv::Mat noise(img.size(), CV_32F);
		cv::RNG rng(params.seed);
		rng.fill(noise, cv::RNG::NORMAL, 0.0, params.noise_sigma);
		img += noise;
	}
	img.convertTo(*ret_image, CV_8U); // rounds and saturates
	return Status();
}

std::vector<BoardPose> calibration_poses(const Calibration &rig, const calib::BoardSpec &board,
					 const cv::Vec3d &target, int per_direction)
{
	per_direction = std::clamp(per_direction, 1, 3);
	std::vector<BoardPose> poses;
	const size_t n = rig.cameras.size();
	if (!n)
		return poses;
	// "Down" of the rig: the cameras' mean y axis.
	cv::Vec3d down(0, 0, 0);
	for (const CameraModel &c : rig.cameras)
		down += cv::Vec3d(c.R(1, 0), c.R(1, 1), c.R(1, 2));
	down /= cv::norm(down);
	// Directions the board faces: each camera, and halfway between consecutive cameras.
	std::vector<cv::Vec3d> facing;
	for (size_t i = 0; i < n; i++) {
		cv::Vec3d d = rig.cameras[i].centre() - target;
		facing.push_back(d / cv::norm(d));
		if (i + 1 < n) {
			cv::Vec3d e = rig.cameras[i + 1].centre() - target;
			e = d / cv::norm(d) + e / cv::norm(e);
			facing.push_back(e / cv::norm(e));
		}
	}
	const cv::Vec3d centre((board.cols - 1) * board.square_mm / 2,
			       (board.rows - 1) * board.square_mm / 2, 0);
	// Three poses per direction: tilted up, tilted down (about the board's horizontal axis) and
	// swung sideways, each rolled a little in its plane and moved off the target a little, so
	// that every camera's intrinsics (principal point, distortion) are well constrained.
	const double tilt[3] = {35, -35, 8}, swing[3] = {8, -6, 32}, roll[3] = {-12, 9, 4};
	int k = 0;
	for (const cv::Vec3d &f : facing)
		for (int j = 0; j < per_direction; j++, k++) {
			const cv::Vec3d z = -f; // into the board, away from the cameras it faces
			cv::Vec3d x = down.cross(z);
			x /= cv::norm(x);
			const cv::Vec3d y = z.cross(x);
			const cv::Matx33d B(x[0], y[0], z[0], x[1], y[1], z[1], x[2], y[2], z[2]);
			const double side = (k % 2) ? 1 : -1;
			BoardPose p;
			p.R = B * axis_rotation({1, 0, 0}, tilt[j]) *
			      axis_rotation({0, 1, 0}, side * swing[j]) * axis_rotation({0, 0, 1}, roll[j]);
			const cv::Vec3d offset(((k * 37) % 41 - 20) * 1.0, ((k * 23) % 31 - 15) * 1.0,
					       ((k * 53) % 61 - 30) * 1.0);
			p.t = target + offset - p.R * centre;
			poses.push_back(p);
		}
	return poses;
}

} // namespace facescan::sim
