// Stage 6a: bundle adjustment of the extrinsics on the code's tracks. See bundle.hpp.
//
// Only the 6 pose parameters per camera are unknowns: each track's point is triangulated from
// the current poses inside the cost (linear, then a Gauss-Newton step on its reprojection),
// so the problem has 24 parameters, not thousands, and Eigen's Levenberg-Marquardt with a
// numerical Jacobian solves it in a few milliseconds. The intrinsics stay as calibrated: a
// principal point or focal error of a few tenths of a pixel is taken up by a small rotation.
#include "recon/bundle.hpp"

#include <opencv2/calib3d.hpp>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <opencv2/core/eigen.hpp>
#include <opencv2/core/utility.hpp>
#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <map>
#include <tuple>

namespace facescan::recon {

namespace {

struct Observation {
	int camera;
	Eigen::Vector2d xy; // undistorted, normalised image coordinates
};

struct Pose {
	Eigen::Matrix3d R;
	Eigen::Vector3d T;
};

// The cameras' poses for parameter vector x: per camera, a rotation vector (in units of the
// rotation sigma) applied before the calibrated rotation, and a centre offset (in units of the
// centre sigma).
std::vector<Pose> poses_at(const std::vector<CameraModel> &cams, const BundleParams &params, const Eigen::VectorXd &x)
{
	std::vector<Pose> out(cams.size());
	for (size_t c = 0; c < cams.size(); ++c) {
		const cv::Vec3d w(x[Eigen::Index(6 * c)], x[Eigen::Index(6 * c + 1)], x[Eigen::Index(6 * c + 2)]);
		cv::Matx33d dR;
		cv::Rodrigues(w * params.sigma_rotation_rad, dR);
		const cv::Matx33d R = dR * cams[c].R;
		const cv::Vec3d C = cams[c].centre() + cv::Vec3d(x[Eigen::Index(6 * c + 3)], x[Eigen::Index(6 * c + 4)],
								 x[Eigen::Index(6 * c + 5)]) *
							       params.sigma_centre_mm;
		cv::cv2eigen(R, out[c].R);
		cv::cv2eigen(-(R * C), out[c].T);
	}
	return out;
}

// The point that best explains one track's observations under `poses`; false when it lies
// behind a camera or the views are degenerate.
bool triangulate_track(const std::vector<Pose> &poses, const Observation *obs, size_t count, Eigen::Vector3d *ret)
{
	Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
	Eigen::Vector3d b = Eigen::Vector3d::Zero();
	for (size_t k = 0; k < count; ++k) {
		const Pose &p = poses[size_t(obs[k].camera)];
		for (int r = 0; r < 2; ++r) {
			const Eigen::RowVector3d row = obs[k].xy[r] * p.R.row(2) - p.R.row(r);
			const double rhs = p.T[r] - obs[k].xy[r] * p.T[2];
			A += row.transpose() * row;
			b += row.transpose() * rhs;
		}
	}
	Eigen::LDLT<Eigen::Matrix3d> ldlt(A);
	if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12))
		return false;
	Eigen::Vector3d X = ldlt.solve(b);
	// One Gauss-Newton step on the normalised reprojection error: the linear solution weighs
	// the views by depth.
	for (int it = 0; it < 1; ++it) {
		Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
		Eigen::Vector3d g = Eigen::Vector3d::Zero();
		for (size_t k = 0; k < count; ++k) {
			const Pose &p = poses[size_t(obs[k].camera)];
			const Eigen::Vector3d Xc = p.R * X + p.T;
			if (!(Xc[2] > 1e-6))
				return false;
			const double iz = 1.0 / Xc[2];
			const Eigen::Vector2d r(Xc[0] * iz - obs[k].xy[0], Xc[1] * iz - obs[k].xy[1]);
			Eigen::Matrix<double, 2, 3> J;
			J << iz, 0, -Xc[0] * iz * iz, 0, iz, -Xc[1] * iz * iz;
			const Eigen::Matrix<double, 2, 3> JR = J * p.R;
			H += JR.transpose() * JR;
			g += JR.transpose() * r;
		}
		Eigen::LDLT<Eigen::Matrix3d> step(H);
		if (step.info() != Eigen::Success)
			return false;
		X -= step.solve(g);
	}
	for (size_t k = 0; k < count; ++k) {
		const Pose &p = poses[size_t(obs[k].camera)];
		if (!((p.R * X + p.T)[2] > 1e-6))
			return false;
	}
	*ret = X;
	return true;
}

struct Problem {
	const std::vector<CameraModel> *cams;
	const BundleParams *params;
	std::vector<Observation> obs;		// grouped by track
	std::vector<std::pair<size_t, size_t>> tracks; // [begin, end) into obs
	std::vector<double> weight;		// per observation (Huber)

	// Pixel residuals of every observation (x then y), 0 for a track that cannot be triangulated.
	void residuals(const Eigen::VectorXd &x, Eigen::VectorXd *r) const
	{
		const std::vector<Pose> poses = poses_at(*cams, *params, x);
		r->setZero(Eigen::Index(2 * obs.size()));
		// Tracks are independent and each writes only its own observations' residuals; the
		// numerical Jacobian evaluates this 6 n + 1 times per step, the stage's whole cost.
		cv::parallel_for_(cv::Range(0, int(tracks.size())), [&](const cv::Range &range) {
			for (int t = range.start; t < range.end; ++t) {
				const auto &[begin, end] = tracks[size_t(t)];
				Eigen::Vector3d X;
				if (!triangulate_track(poses, &obs[begin], end - begin, &X))
					continue;
				for (size_t k = begin; k < end; ++k) {
					const Pose &p = poses[size_t(obs[k].camera)];
					const CameraModel &c = (*cams)[size_t(obs[k].camera)];
					const Eigen::Vector3d Xc = p.R * X + p.T;
					(*r)[Eigen::Index(2 * k)] = c.K(0, 0) * (Xc[0] / Xc[2] - obs[k].xy[0]);
					(*r)[Eigen::Index(2 * k + 1)] = c.K(1, 1) * (Xc[1] / Xc[2] - obs[k].xy[1]);
				}
			}
		});
	}
};

// The cost Eigen's Levenberg-Marquardt minimises: weighted reprojection residuals in units of
// sigma_px, then the prior (the parameters themselves, already in sigmas).
struct Cost {
	using Scalar = double;
	enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
	using InputType = Eigen::VectorXd;
	using ValueType = Eigen::VectorXd;
	using JacobianType = Eigen::MatrixXd;

	const Problem *problem = nullptr;

	int inputs() const { return int(6 * problem->cams->size()); }
	int values() const { return int(2 * problem->obs.size() + 6 * problem->cams->size()); }
	int operator()(const Eigen::VectorXd &x, Eigen::VectorXd &fvec) const
	{
		Eigen::VectorXd r;
		problem->residuals(x, &r);
		const double s = 1.0 / problem->params->sigma_px;
		for (size_t k = 0; k < problem->obs.size(); ++k) {
			const double w = std::sqrt(problem->weight[k]) * s;
			fvec[Eigen::Index(2 * k)] = r[Eigen::Index(2 * k)] * w;
			fvec[Eigen::Index(2 * k + 1)] = r[Eigen::Index(2 * k + 1)] * w;
		}
		fvec.tail(x.size()) = x;
		return 0;
	}
};

double rms_px(const Eigen::VectorXd &r)
{
	return r.size() ? std::sqrt(r.squaredNorm() / double(r.size() / 2)) : 0.0;
}

// The robust data cost: sum over observations of Huber's rho of the pixel error.
double huber_cost(const Eigen::VectorXd &r, double k)
{
	double sum = 0;
	for (Eigen::Index i = 0; i + 1 < r.size(); i += 2) {
		const double e = std::hypot(r[i], r[i + 1]);
		sum += e <= k ? 0.5 * e * e : k * (e - 0.5 * k);
	}
	return sum;
}

// The images fix the cameras relative to each other, not where the rig stands: a common turn of
// all cameras about the head costs the prior little and the images nothing, and it would move the
// whole face. The refined rig is put back where the calibration had it on average — the
// similarity that best maps its cameras' centres and axes (at the rig's scale) onto the
// calibrated ones (Umeyama) — which changes no image residual.
void keep_gauge(const std::vector<CameraModel> &cams, std::vector<Pose> *poses)
{
	const int n = int(cams.size());
	Eigen::Matrix3Xd centres(3, n);
	for (int c = 0; c < n; ++c) {
		Eigen::Vector3d C;
		cv::cv2eigen(cams[size_t(c)].centre(), C);
		centres.col(c) = C;
	}
	const Eigen::Vector3d mean = centres.rowwise().mean();
	const double L0 = (centres.colwise() - mean).colwise().norm().mean();
	const double L = std::max(L0, 1.0);
	Eigen::Matrix3Xd src(3, 4 * n), dst(3, 4 * n);
	for (int c = 0; c < n; ++c) {
		const Pose &p = (*poses)[size_t(c)];
		const Eigen::Vector3d Cn = -p.R.transpose() * p.T;
		Eigen::Matrix3d R0;
		cv::cv2eigen(cams[size_t(c)].R, R0);
		const Eigen::Vector3d Co = centres.col(c);
		src.col(4 * c) = Cn;
		dst.col(4 * c) = Co;
		for (int k = 0; k < 3; ++k) {
			src.col(4 * c + 1 + k) = Cn + L * p.R.row(k).transpose();
			dst.col(4 * c + 1 + k) = Co + L * R0.row(k).transpose();
		}
	}
	const Eigen::Matrix4d S = Eigen::umeyama(src, dst, true);
	const double scale = S.block<3, 3>(0, 0).col(0).norm();
	const Eigen::Matrix3d Om = S.block<3, 3>(0, 0) / scale;
	for (Pose &p : *poses) {
		const Eigen::Vector3d Cn = -p.R.transpose() * p.T;
		const Eigen::Vector3d Cs = S.block<3, 3>(0, 0) * Cn + S.block<3, 1>(0, 3);
		p.R = p.R * Om.transpose();
		p.T = -p.R * Cs;
	}
}

} // namespace

Status refine_extrinsics(const std::vector<PairMatches> &pairs, const BundleParams &params,
			 std::vector<CameraModel> *cameras, BundleStats *stats)
{
	*stats = BundleStats();
	const int n = int(cameras->size());
	for (const PairMatches &pm : pairs)
		if (pm.cam_a < 0 || pm.cam_a >= n || pm.cam_b < 0 || pm.cam_b >= n || pm.cam_a == pm.cam_b)
			return Status::error(-EINVAL, "bundle adjustment: a pair names a camera outside the calibration");
	if (!params.enabled || n < 2)
		return {};

	// Tracks: a feature of one square in one camera is one image point; pair matches that share
	// one are the same surface point (union-find over the image points).
	std::map<std::tuple<int, int, int>, int> point_id;
	std::vector<cv::Point2d> point_px;
	std::vector<int> point_cam, parent;
	auto id_of = [&](int cam, int square, int feature, const cv::Point2d &px) {
		auto [it, added] = point_id.try_emplace({cam, square, feature}, int(parent.size()));
		if (added) {
			parent.push_back(it->second);
			point_px.push_back(px);
			point_cam.push_back(cam);
		}
		return it->second;
	};
	auto root = [&](int i) {
		while (parent[size_t(i)] != i)
			i = parent[size_t(i)] = parent[size_t(parent[size_t(i)])];
		return i;
	};
	for (const PairMatches &pm : pairs)
		for (const PointMatch &m : pm.matches) {
			// Corners only. A corner is where two edges cross, one surface point in every view;
			// the centroid of a square's image is not the image of one surface point (perspective
			// and relief shift it differently in each view). At the true calibration of a
			// held-out scene (booth 3004, scanned head) corners were 0.05-0.11 px off their
			// epipolar geometry, centroids 0.3-0.7 px; their common pull turned a pair by
			// 0.3 mrad and moved its sheet 0.7 mm.
			if (m.square_a < 0 || m.square_b < 0 || m.feature == kCentroid)
				continue;
			const int a = id_of(pm.cam_a, m.square_a, m.feature, m.a);
			const int b = id_of(pm.cam_b, m.square_b, m.feature, m.b);
			parent[size_t(root(a))] = root(b);
		}
	// Undistorted once: the intrinsics do not change.
	std::vector<cv::Point2d> xy(point_px.size());
	for (int c = 0; c < n; ++c) {
		std::vector<cv::Point2d> in, out;
		std::vector<size_t> idx;
		for (size_t i = 0; i < point_px.size(); ++i)
			if (point_cam[i] == c) {
				in.push_back(point_px[i]);
				idx.push_back(i);
			}
		if (in.empty())
			continue;
		const CameraModel &cam = (*cameras)[size_t(c)];
		cv::undistortPoints(in, out, cam.K, cam.dist);
		for (size_t k = 0; k < idx.size(); ++k)
			xy[idx[k]] = out[k];
	}
	std::map<int, std::vector<int>> members;
	for (size_t i = 0; i < parent.size(); ++i)
		members[root(int(i))].push_back(int(i));

	Problem problem;
	problem.cams = cameras;
	problem.params = &params;
	for (const auto &[r, list] : members) {
		(void)r;
		// One view per camera: two image points of one camera in one track mean two squares
		// were merged by mistake.
		std::vector<int> cams_seen;
		for (int i : list)
			cams_seen.push_back(point_cam[size_t(i)]);
		std::sort(cams_seen.begin(), cams_seen.end());
		if (std::adjacent_find(cams_seen.begin(), cams_seen.end()) != cams_seen.end() || list.size() < 2)
			continue;
		const size_t begin = problem.obs.size();
		for (int i : list)
			problem.obs.push_back({point_cam[size_t(i)],
					       Eigen::Vector2d(xy[size_t(i)].x, xy[size_t(i)].y)});
		problem.tracks.push_back({begin, problem.obs.size()});
		stats->tracks_3_views += list.size() >= 3;
	}
	stats->tracks = int(problem.tracks.size());
	stats->observations = int(problem.obs.size());
	if (stats->tracks < params.min_tracks)
		return {};

	Eigen::VectorXd x = Eigen::VectorXd::Zero(6 * n);
	Eigen::VectorXd r;
	problem.weight.assign(problem.obs.size(), 1.0);
	problem.residuals(x, &r);
	stats->rms_before_px = rms_px(r);
	const double cost_before = huber_cost(r, params.huber_px);
	for (int round = 0; round < std::max(1, params.reweight_rounds); ++round) {
		// Huber weights from the current residuals: past huber_px an observation counts as if
		// its error grew linearly, so a wrong match pulls with a bounded force.
		for (size_t k = 0; k < problem.obs.size(); ++k) {
			const double e = std::hypot(r[Eigen::Index(2 * k)], r[Eigen::Index(2 * k + 1)]);
			problem.weight[k] = e <= params.huber_px ? 1.0 : params.huber_px / e;
		}
		Cost cost;
		cost.problem = &problem;
		Eigen::NumericalDiff<Cost> diff(cost);
		Eigen::LevenbergMarquardt<Eigen::NumericalDiff<Cost>, double> lm(diff);
		lm.parameters.maxfev = params.max_iterations * (6 * n + 1);
		lm.minimize(x);
		problem.residuals(x, &r);
	}
	stats->rms_after_px = rms_px(r);
	// A refinement that explains the images worse than the calibration did is not applied.
	if (!x.allFinite() || !(huber_cost(r, params.huber_px) <= cost_before))
		return {};
	std::vector<Pose> poses = poses_at(*cameras, params, x);
	keep_gauge(*cameras, &poses);
	for (int c = 0; c < n; ++c) {
		CameraModel &cam = (*cameras)[size_t(c)];
		const Pose &p = poses[size_t(c)];
		Eigen::Matrix3d R0;
		Eigen::Vector3d C0;
		cv::cv2eigen(cam.R, R0);
		cv::cv2eigen(cam.centre(), C0);
		const double moved = (-p.R.transpose() * p.T - C0).norm();
		const double turned = Eigen::AngleAxisd(p.R * R0.transpose()).angle();
		stats->cameras.push_back({c, turned * 1e3, moved});
		cv::eigen2cv(p.R, cam.R);
		cv::eigen2cv(p.T, cam.T);
	}
	stats->applied = true;
	return {};
}

} // namespace facescan::recon
