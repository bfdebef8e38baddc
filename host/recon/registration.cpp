// Stage 8: registration. See registration.hpp.
#include "recon/registration.hpp"

#include <opencv2/core/utility.hpp>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
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

Status overlap_distance(const std::vector<cv::Point3f> &moving, const std::vector<cv::Point3f> &fixed,
			const cv::Matx33d &R, const cv::Vec3d &T, const RegistrationParams &params,
			double *ret_before_mm, double *ret_after_mm)
{
	if (moving.empty() || fixed.empty())
		return Status::error(-ENODATA, "overlap: an empty cloud");
	if (!(params.dense_reach_mm > 0))
		return Status::error(-EINVAL, "overlap: the reach must be positive");
	// Only distances within the reach matter (beyond it a point is no overlap, and the cap is
	// below it), so the fixed cloud is bucketed by cells of the reach and a query looks at its
	// cell and the 26 around it: exact, where a k-d tree over the whole cloud cost 0.3-0.6 s
	// per pair (its build and approximate search over 100-200k points).
	const double cell = params.dense_reach_mm;
	// Points farther than a kilometre (and NaN ones) are no surface: they are left out, which
	// also keeps a 4 mm cell's index within the 21 bits per axis its key packs. (With a smaller
	// reach two cells may share a key: their points are then both measured, never missed.)
	auto on_grid = [](const cv::Vec3d &p) {
		return std::fabs(p[0]) < 1e6 && std::fabs(p[1]) < 1e6 && std::fabs(p[2]) < 1e6;
	};
	auto cell_of = [cell](const cv::Vec3d &p) {
		return cv::Vec3i(int(std::floor(p[0] / cell)), int(std::floor(p[1] / cell)), int(std::floor(p[2] / cell)));
	};
	auto key_of = [](const cv::Vec3i &c) {
		return (int64_t(c[0] & 0x1fffff) << 42) | (int64_t(c[1] & 0x1fffff) << 21) | int64_t(c[2] & 0x1fffff);
	};
	std::vector<std::pair<int64_t, uint32_t>> keyed;
	keyed.reserve(fixed.size());
	for (size_t i = 0; i < fixed.size(); ++i) {
		const cv::Vec3d p(fixed[i].x, fixed[i].y, fixed[i].z);
		if (on_grid(p))
			keyed.emplace_back(key_of(cell_of(p)), uint32_t(i));
	}
	std::sort(keyed.begin(), keyed.end());
	std::unordered_map<int64_t, std::pair<uint32_t, uint32_t>> cells; // key -> [begin, end) in keyed
	cells.reserve(keyed.size() / 8 + 16);
	for (size_t i = 0; i < keyed.size();) {
		size_t j = i;
		while (j < keyed.size() && keyed[j].first == keyed[i].first)
			++j;
		cells.emplace(keyed[i].first, std::make_pair(uint32_t(i), uint32_t(j)));
		i = j;
	}
	const float reach2 = float(params.dense_reach_mm * params.dense_reach_mm);
	auto nearest2 = [&](const cv::Vec3d &q) {
		float best = std::numeric_limits<float>::infinity();
		if (!on_grid(q))
			return best;
		const cv::Vec3i c = cell_of(q);
		const cv::Point3f qf{float(q[0]), float(q[1]), float(q[2])};
		for (int dx = -1; dx <= 1; ++dx)
			for (int dy = -1; dy <= 1; ++dy)
				for (int dz = -1; dz <= 1; ++dz) {
					const auto it = cells.find(key_of(c + cv::Vec3i(dx, dy, dz)));
					if (it == cells.end())
						continue;
					for (uint32_t k = it->second.first; k < it->second.second; ++k) {
						const cv::Point3f d = fixed[keyed[k].second] - qf;
						best = std::min(best, d.dot(d));
					}
				}
		return best;
	};
	const int stride = std::max(1, params.dense_stride);
	const int n = int((moving.size() + size_t(stride) - 1) / size_t(stride));
	std::vector<float> d0(static_cast<size_t>(n)), d1(static_cast<size_t>(n)); // squared distances
	cv::parallel_for_(cv::Range(0, n), [&](const cv::Range &range) {
		for (int i = range.start; i < range.end; ++i) {
			const cv::Point3f &p = moving[size_t(i) * size_t(stride)];
			const cv::Vec3d q(p.x, p.y, p.z);
			d0[size_t(i)] = nearest2(q);
			d1[size_t(i)] = nearest2(R * q + T);
		}
	});
	double sum0 = 0, sum1 = 0;
	int count = 0;
	for (int i = 0; i < n; ++i) {
		const float a = d0[size_t(i)], b = d1[size_t(i)];
		if (a > reach2 && b > reach2)
			continue;
		sum0 += std::min(double(std::sqrt(a)), params.dense_cap_mm);
		sum1 += std::min(double(std::sqrt(b)), params.dense_cap_mm);
		count++;
	}
	if (count == 0)
		return Status::error(-ENODATA, "overlap: the clouds do not overlap");
	*ret_before_mm = sum0 / count;
	*ret_after_mm = sum1 / count;
	return {};
}

Status register_dense(std::vector<std::vector<cv::Point3f>> *clouds, const RegistrationParams &params,
		      std::vector<RegistrationPair> *pairs)
{
	for (RegistrationPair &rp : *pairs) {
		rp.applied_dense = false;
		if (!rp.applied || rp.model < 0 || rp.onto < 0 || size_t(rp.model) >= clouds->size() ||
		    size_t(rp.onto) >= clouds->size())
			continue;
		std::vector<cv::Point3f> &moving = (*clouds)[size_t(rp.model)];
		Status s = overlap_distance(moving, (*clouds)[size_t(rp.onto)], rp.R, rp.T, params, &rp.dense_before_mm,
					    &rp.dense_after_mm);
		if (s.code() == -ENODATA)
			continue; // nothing to judge by: no move (a lone cloud cannot be off its neighbour)
		if (!s.ok())
			return s;
		if (!(rp.dense_after_mm < (1.0 - params.dense_min_improvement) * rp.dense_before_mm))
			continue;
		rp.applied_dense = true;
		for (cv::Point3f &q : moving)
			q = cv::Point3f(rp.R * cv::Vec3d(q.x, q.y, q.z) + rp.T);
	}
	return {};
}

} // namespace facescan::recon
