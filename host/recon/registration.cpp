// Stage 8: registration. See registration.hpp.
#include "recon/registration.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace facescan::recon {

namespace {

int64_t key(int camera, int square, int feature)
{
	return (int64_t(camera) << 40) | (int64_t(square) << 4) | int64_t(feature);
}

double mean_sq(const std::vector<cv::Point3d> &q, const std::vector<cv::Point3d> &p, const cv::Matx33d &R,
	       const cv::Vec3d &T)
{
	if (q.empty())
		return 0;
	double s = 0;
	for (size_t i = 0; i < q.size(); ++i) {
		const cv::Vec3d d = cv::Vec3d(p[i]) - (R * cv::Vec3d(q[i]) + T);
		s += d.dot(d);
	}
	return s / double(q.size());
}

} // namespace

std::vector<std::pair<int, int>> shared_points(const PartialModel &a, const PartialModel &b)
{
	std::vector<std::pair<int, int>> out;
	// The camera the two pairs have in common, and which side of each pair it is.
	int cam = -1;
	bool a_first = false, b_first = false;
	for (int ca : {a.cam_a, a.cam_b})
		for (int cb : {b.cam_a, b.cam_b})
			if (ca == cb && ca >= 0) {
				cam = ca;
				a_first = ca == a.cam_a;
				b_first = cb == b.cam_a;
			}
	if (cam < 0)
		return out;
	std::unordered_map<int64_t, int> index;
	for (size_t i = 0; i < a.sources.size(); ++i) {
		const PointMatch &m = a.sources[i];
		index.emplace(key(cam, a_first ? m.square_a : m.square_b, m.feature), int(i));
	}
	for (size_t j = 0; j < b.sources.size(); ++j) {
		const PointMatch &m = b.sources[j];
		auto it = index.find(key(cam, b_first ? m.square_a : m.square_b, m.feature));
		if (it != index.end())
			out.emplace_back(it->second, int(j));
	}
	return out;
}

Status rigid_fit(const std::vector<cv::Point3d> &q, const std::vector<cv::Point3d> &p, cv::Matx33d *ret_R,
		 cv::Vec3d *ret_T)
{
	if (q.size() != p.size() || q.size() < 3)
		return Status::error(-EINVAL, "rigid_fit: need at least 3 point pairs, have " +
						      std::to_string(std::min(q.size(), p.size())));
	Eigen::Matrix3Xd src(3, q.size()), dst(3, p.size());
	for (size_t i = 0; i < q.size(); ++i) {
		src.col(long(i)) << q[i].x, q[i].y, q[i].z;
		dst.col(long(i)) << p[i].x, p[i].y, p[i].z;
	}
	// Degenerate when the centred source has rank < 2 (all points on a line).
	const Eigen::Vector3d mean = src.rowwise().mean();
	const Eigen::Matrix3d cov = (src.colwise() - mean) * (src.colwise() - mean).transpose();
	Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
	if (es.eigenvalues()(1) <= 1e-9 * std::max(1.0, es.eigenvalues()(2)))
		return Status::error(-EINVAL, "rigid_fit: points are collinear");
	const Eigen::Matrix4d M = Eigen::umeyama(src, dst, false);
	for (int r = 0; r < 3; ++r) {
		for (int c = 0; c < 3; ++c)
			(*ret_R)(r, c) = M(r, c);
		(*ret_T)(r) = M(r, 3);
	}
	return {};
}

Status register_models(std::vector<PartialModel> *models, const RegistrationParams &params,
		       std::vector<RegistrationPair> *ret_pairs)
{
	std::vector<RegistrationPair> pairs;
	const int n = int(models->size());
	if (n == 0)
		return Status::error(-EINVAL, "register_models: no models");
	const int ref = params.reference >= 0 ? params.reference : (n - 1) / 2;
	if (ref >= n)
		return Status::error(-EINVAL, "register_models: reference " + std::to_string(ref) + " of " +
						      std::to_string(n) + " models");
	// Outward from the reference: each model onto its already-registered neighbour.
	std::vector<std::pair<int, int>> order;
	for (int i = ref - 1; i >= 0; --i)
		order.emplace_back(i, i + 1);
	for (int i = ref + 1; i < n; ++i)
		order.emplace_back(i, i - 1);
	for (const auto &[mi, oi] : order) {
		PartialModel &m = (*models)[size_t(mi)];
		const PartialModel &o = (*models)[size_t(oi)];
		RegistrationPair rp;
		rp.model = mi;
		rp.onto = oi;
		const std::vector<std::pair<int, int>> sh = shared_points(m, o);
		rp.shared = int(sh.size());
		std::vector<cv::Point3d> q, p;
		for (const auto &[i, j] : sh) {
			q.push_back(m.points[size_t(i)]);
			p.push_back(o.points[size_t(j)]);
		}
		const cv::Matx33d I = cv::Matx33d::eye();
		const cv::Vec3d Z(0, 0, 0);
		rp.d_before_all = mean_sq(q, p, I, Z);
		rp.d_before = rp.d_after = rp.d_after_all = rp.d_before_all;
		rp.inliers = rp.shared;
		if (rp.shared >= std::max(3, params.min_points)) {
			cv::Matx33d R;
			cv::Vec3d T;
			Status s = rigid_fit(q, p, &R, &T);
			if (s.ok()) {
				// Trim: refit on the pairs whose residual is within factor * median.
				std::vector<double> res(q.size());
				for (size_t k = 0; k < q.size(); ++k)
					res[k] = cv::norm(cv::Vec3d(p[k]) - (R * cv::Vec3d(q[k]) + T));
				std::vector<double> sorted = res;
				std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
				const double limit = std::max(params.outlier_factor * sorted[sorted.size() / 2],
							      params.outlier_floor_mm);
				std::vector<cv::Point3d> qi, pi;
				for (size_t k = 0; k < q.size(); ++k)
					if (res[k] <= limit) {
						qi.push_back(q[k]);
						pi.push_back(p[k]);
					}
				if (int(qi.size()) >= std::max(3, params.min_points) && int(qi.size()) < rp.shared) {
					cv::Matx33d R2;
					cv::Vec3d T2;
					if (rigid_fit(qi, pi, &R2, &T2).ok()) {
						R = R2;
						T = T2;
					}
				} else {
					qi = q;
					pi = p;
				}
				rp.inliers = int(qi.size());
				rp.d_before = mean_sq(qi, pi, I, Z);
				const double d_fit = mean_sq(qi, pi, R, T);
				if (d_fit < (1.0 - params.min_improvement) * rp.d_before) {
					rp.d_after = d_fit;
					rp.d_after_all = mean_sq(q, p, R, T);
					rp.R = R;
					rp.T = T;
					rp.applied = true;
					for (cv::Point3d &x : m.points)
						x = cv::Point3d(R * cv::Vec3d(x) + T);
				} else {
					rp.d_after = rp.d_before;
				}
			}
		}
		pairs.push_back(rp);
	}
	if (ret_pairs)
		*ret_pairs = std::move(pairs);
	return {};
}

} // namespace facescan::recon
