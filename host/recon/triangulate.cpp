// Stage 6: triangulation. See triangulate.hpp.
#include "recon/triangulate.hpp"

#include <opencv2/calib3d.hpp>

#include <Eigen/Dense>

#include <cmath>

namespace facescan::recon {

namespace {

std::vector<cv::Point2d> undistort(const CameraModel &cam, const std::vector<cv::Point2d> &px)
{
	std::vector<cv::Point2d> out;
	if (px.empty())
		return out;
	// More iterations than OpenCV's default 5: the booth's lenses can have strong radial terms.
	cv::undistortPoints(px, out, cv::Mat(cam.K), cv::Mat(cam.dist), cv::noArray(), cv::noArray(),
			    cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 1e-12));
	return out;
}

struct View {
	Eigen::Matrix3d R;
	Eigen::Vector3d T;
	double f; // mean focal length: weights normalised residuals as pixels
};

View make_view(const CameraModel &cam)
{
	View v;
	for (int r = 0; r < 3; ++r) {
		for (int c = 0; c < 3; ++c)
			v.R(r, c) = cam.R(r, c);
		v.T(r) = cam.T(r);
	}
	v.f = 0.5 * (cam.K(0, 0) + cam.K(1, 1));
	return v;
}

// Linear triangulation from normalised coordinates: each view gives two rows of
// (x * r3 - r1) X = t1 - x * t3; solved in least squares.
Eigen::Vector3d linear(const View &a, const cv::Point2d &xa, const View &b, const cv::Point2d &xb)
{
	Eigen::Matrix<double, 4, 3> A;
	Eigen::Vector4d rhs;
	const View *views[2] = {&a, &b};
	const cv::Point2d *xs[2] = {&xa, &xb};
	for (int k = 0; k < 2; ++k) {
		const View &v = *views[k];
		const cv::Point2d &x = *xs[k];
		A.row(2 * k) = x.x * v.R.row(2) - v.R.row(0);
		A.row(2 * k + 1) = x.y * v.R.row(2) - v.R.row(1);
		rhs(2 * k) = v.T(0) - x.x * v.T(2);
		rhs(2 * k + 1) = v.T(1) - x.y * v.T(2);
	}
	const Eigen::Matrix3d AtA = A.transpose() * A;
	const Eigen::Vector3d Atb = A.transpose() * rhs;
	return AtA.ldlt().solve(Atb);
}

// Gauss-Newton on the focal-weighted normalised reprojection error of both views.
Eigen::Vector3d refine(const View &a, const cv::Point2d &xa, const View &b, const cv::Point2d &xb,
		       Eigen::Vector3d X, int iterations)
{
	const View *views[2] = {&a, &b};
	const cv::Point2d *xs[2] = {&xa, &xb};
	for (int it = 0; it < iterations; ++it) {
		Eigen::Matrix<double, 4, 3> J;
		Eigen::Vector4d r;
		bool ok = true;
		for (int k = 0; k < 2; ++k) {
			const View &v = *views[k];
			const Eigen::Vector3d p = v.R * X + v.T;
			if (p(2) <= 1e-9) {
				ok = false;
				break;
			}
			const double iz = 1.0 / p(2);
			r(2 * k) = v.f * (p(0) * iz - xs[k]->x);
			r(2 * k + 1) = v.f * (p(1) * iz - xs[k]->y);
			J.row(2 * k) = v.f * iz * (v.R.row(0) - p(0) * iz * v.R.row(2));
			J.row(2 * k + 1) = v.f * iz * (v.R.row(1) - p(1) * iz * v.R.row(2));
		}
		if (!ok)
			break;
		const Eigen::Matrix3d JtJ = J.transpose() * J;
		const Eigen::Vector3d step = JtJ.ldlt().solve(J.transpose() * r);
		if (!step.allFinite())
			break;
		X -= step;
		if (step.norm() < 1e-9)
			break;
	}
	return X;
}

bool valid_camera(const CameraModel &cam)
{
	return cam.K(0, 0) > 0 && cam.K(1, 1) > 0 && cam.K(2, 2) == 1.0;
}

} // namespace

std::vector<cv::Point2d> project_points(const CameraModel &cam, const std::vector<cv::Point3d> &points)
{
	std::vector<cv::Point2d> out;
	if (points.empty())
		return out;
	cv::Vec3d rvec;
	cv::Rodrigues(cv::Mat(cam.R), rvec);
	cv::projectPoints(points, rvec, cam.T, cv::Mat(cam.K), cv::Mat(cam.dist), out);
	return out;
}

Status triangulate_pair(const PairMatches &pair, const CameraModel &cam_a, const CameraModel &cam_b,
			const TriangulateParams &params, PartialModel *ret_model, TriangulateStats *ret_stats)
{
	if (!valid_camera(cam_a) || !valid_camera(cam_b))
		return Status::error(-EINVAL, "triangulate: camera " + std::to_string(pair.cam_a) + " or " +
						      std::to_string(pair.cam_b) + " has no valid intrinsic matrix");
	const size_t n = pair.matches.size();
	std::vector<cv::Point2d> pa(n), pb(n);
	for (size_t i = 0; i < n; ++i) {
		pa[i] = pair.matches[i].a;
		pb[i] = pair.matches[i].b;
	}
	const std::vector<cv::Point2d> na = undistort(cam_a, pa), nb = undistort(cam_b, pb);
	const View va = make_view(cam_a), vb = make_view(cam_b);

	TriangulateStats stats;
	stats.input = int(n);
	std::vector<cv::Point3d> X(n);
	std::vector<char> in_front(n, 0);
	for (size_t i = 0; i < n; ++i) {
		Eigen::Vector3d x = linear(va, na[i], vb, nb[i]);
		x = refine(va, na[i], vb, nb[i], x, params.refine_iterations);
		X[i] = cv::Point3d(x(0), x(1), x(2));
		const double za = (va.R.row(2) * x)(0) + va.T(2), zb = (vb.R.row(2) * x)(0) + vb.T(2);
		in_front[i] = x.allFinite() && za > params.min_depth_mm && zb > params.min_depth_mm;
	}
	// Reproject through the full (distorted) camera model: the error is in the pixels we measured.
	std::vector<cv::Point3d> finite(n);
	for (size_t i = 0; i < n; ++i)
		finite[i] = in_front[i] ? X[i] : cv::Point3d(0, 0, 1e3);
	const std::vector<cv::Point2d> ra = project_points(cam_a, finite), rb = project_points(cam_b, finite);

	PartialModel model;
	model.cam_a = pair.cam_a;
	model.cam_b = pair.cam_b;
	double sum = 0;
	for (size_t i = 0; i < n; ++i) {
		if (!in_front[i]) {
			stats.dropped_depth++;
			continue;
		}
		const double err = 0.5 * (cv::norm(ra[i] - pa[i]) + cv::norm(rb[i] - pb[i]));
		if (!(err <= params.max_reprojection_px)) {
			stats.dropped_reprojection++;
			continue;
		}
		model.points.push_back(X[i]);
		model.sources.push_back(pair.matches[i]);
		model.reprojection_px.push_back(err);
		sum += err;
	}
	stats.kept = int(model.points.size());
	stats.mean_reprojection_px = stats.kept ? sum / stats.kept : 0;
	*ret_model = std::move(model);
	if (ret_stats)
		*ret_stats = stats;
	return {};
}

cv::Vec3d axes_meet(const CameraModel &a, const CameraModel &b)
{
	const cv::Vec3d ca = a.centre(), cb = b.centre();
	const cv::Vec3d da = a.R.t() * cv::Vec3d(0, 0, 1), db = b.R.t() * cv::Vec3d(0, 0, 1);
	const cv::Vec3d w = ca - cb;
	const double A = da.dot(da), B = da.dot(db), C = db.dot(db), D = da.dot(w), E = db.dot(w);
	const double den = A * C - B * B;
	if (std::fabs(den) < 1e-9)
		return ca + da * 500.0;
	const double s = (B * E - C * D) / den, t = (A * E - B * D) / den;
	return ((ca + da * s) + (cb + db * t)) * 0.5;
}

} // namespace facescan::recon
