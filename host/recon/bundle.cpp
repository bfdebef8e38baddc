// Stage 6a: bundle adjustment of the extrinsics on the code's tracks. See bundle.hpp.
//
// Only the 6 pose parameters per camera are unknowns: each track's point is triangulated from
// the current poses inside the cost (linear, then a Gauss-Newton step on its reprojection),
// so the problem has 24 parameters, not thousands, and Eigen's Levenberg-Marquardt with a
// numerical Jacobian solves it in a few milliseconds. The intrinsics stay as calibrated: a
// principal point or focal error of a few tenths of a pixel is taken up by a small rotation.
#include "recon/bundle.hpp"
#include "recon/triangulate.hpp"

#include <opencv2/calib3d.hpp>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <opencv2/core/eigen.hpp>
#include <opencv2/core/utility.hpp>
#include <unsupported/Eigen/NonLinearOptimization>

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
	// 3 x 3: the closed-form inverse (the residuals evaluate this for every track, once per
	// parameter and step); a near-singular system (parallel rays) has no point.
	Eigen::Matrix3d inverse;
	bool invertible = false;
	double det = 0;
	const double scale = A.trace();
	A.computeInverseAndDetWithCheck(inverse, det, invertible, 1e-12 * scale * scale * scale);
	if (!invertible || !(det > 0))
		return false;
	Eigen::Vector3d X = inverse * b;
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
		const double h_scale = H.trace();
		H.computeInverseAndDetWithCheck(inverse, det, invertible, 1e-12 * h_scale * h_scale * h_scale);
		if (!invertible)
			return false;
		X -= inverse * g;
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
	std::vector<std::vector<int>> camera_tracks; // per camera, the tracks that see it

	// Pixel residuals of every observation (x then y), 0 for a track that cannot be triangulated;
	// with `only`, of those tracks' observations alone (the others in *r are left as they are).
	void residuals(const Eigen::VectorXd &x, Eigen::VectorXd *r, const std::vector<int> *only = nullptr) const
	{
		const std::vector<Pose> poses = poses_at(*cams, *params, x);
		if (!only)
			r->setZero(Eigen::Index(2 * obs.size()));
		// Tracks are independent and each writes only its own observations' residuals; the
		// numerical Jacobian evaluates this once per parameter (over the tracks that parameter's
		// camera sees) and step, the stage's whole cost.
		const int count = int(only ? only->size() : tracks.size());
		cv::parallel_for_(cv::Range(0, count), [&](const cv::Range &range) {
			for (int i = range.start; i < range.end; ++i) {
				const auto &[begin, end] = tracks[size_t(only ? (*only)[size_t(i)] : i)];
				Eigen::Vector3d X;
				if (!triangulate_track(poses, &obs[begin], end - begin, &X)) {
					r->segment(Eigen::Index(2 * begin), Eigen::Index(2 * (end - begin))).setZero();
					continue;
				}
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

	// Forward differences with Eigen::NumericalDiff's step, but a camera's parameters move only
	// the residuals of the tracks that camera sees: each column re-evaluates those alone.
	int df(const Eigen::VectorXd &x, Eigen::MatrixXd &fjac) const
	{
		const double eps = std::sqrt(Eigen::NumTraits<double>::epsilon());
		Eigen::VectorXd r0, r1;
		problem->residuals(x, &r0);
		const double s = 1.0 / problem->params->sigma_px;
		fjac.setZero(values(), inputs());
		for (Eigen::Index j = 0; j < x.size(); ++j) {
			const std::vector<int> &seen = problem->camera_tracks[size_t(j / 6)];
			Eigen::VectorXd xj = x;
			double h = eps * std::fabs(x[j]);
			if (h == 0.)
				h = eps;
			xj[j] += h;
			r1 = r0;
			problem->residuals(xj, &r1, &seen);
			for (int t : seen) {
				const auto &[begin, end] = problem->tracks[size_t(t)];
				for (size_t k = begin; k < end; ++k) {
					const double w = std::sqrt(problem->weight[k]) * s / h;
					fjac(Eigen::Index(2 * k), j) = (r1[Eigen::Index(2 * k)] - r0[Eigen::Index(2 * k)]) * w;
					fjac(Eigen::Index(2 * k + 1), j) =
						(r1[Eigen::Index(2 * k + 1)] - r0[Eigen::Index(2 * k + 1)]) * w;
				}
			}
			fjac(Eigen::Index(2 * problem->obs.size()) + j, j) = 1.0;
		}
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

Status refine_extrinsics(const std::vector<PairMatches> &pairs, const std::vector<Track> &extra_tracks,
			 const BundleParams &params,
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
	std::map<int, std::vector<int>> members;
	for (size_t i = 0; i < parent.size(); ++i)
		members[root(int(i))].push_back(int(i));

	Problem problem;
	problem.cams = cameras;
	problem.params = &params;
	std::vector<cv::Point2d> obs_px; // each observation's pixel, undistorted below
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
		for (int i : list) {
			problem.obs.push_back({point_cam[size_t(i)], Eigen::Vector2d::Zero()});
			obs_px.push_back(point_px[size_t(i)]);
		}
		problem.tracks.push_back({begin, problem.obs.size()});
		stats->tracks_3_views += list.size() >= 3;
	}
	for (const Track &t : extra_tracks) {
		if (t.cameras.size() < 2 || t.cameras.size() != t.pixels.size())
			continue;
		bool inside = true;
		for (int c : t.cameras)
			inside = inside && c >= 0 && c < n;
		if (!inside)
			continue;
		const size_t begin = problem.obs.size();
		for (size_t k = 0; k < t.cameras.size(); ++k) {
			problem.obs.push_back({t.cameras[k], Eigen::Vector2d::Zero()});
			obs_px.push_back(t.pixels[k]);
		}
		problem.tracks.push_back({begin, problem.obs.size()});
		stats->extra_tracks++;
		stats->tracks_3_views += t.cameras.size() >= 3;
	}
	// Undistorted once, per camera: the intrinsics do not change.
	for (int c = 0; c < n; ++c) {
		std::vector<cv::Point2d> in, out;
		std::vector<size_t> idx;
		for (size_t k = 0; k < problem.obs.size(); ++k)
			if (problem.obs[k].camera == c) {
				in.push_back(obs_px[k]);
				idx.push_back(k);
			}
		if (in.empty())
			continue;
		const CameraModel &cam = (*cameras)[size_t(c)];
		cv::undistortPoints(in, out, cam.K, cam.dist);
		for (size_t k = 0; k < idx.size(); ++k)
			problem.obs[idx[k]].xy = Eigen::Vector2d(out[k].x, out[k].y);
	}
	stats->tracks = int(problem.tracks.size());
	problem.camera_tracks.assign(size_t(n), {});
	for (size_t t = 0; t < problem.tracks.size(); ++t)
		for (size_t k = problem.tracks[t].first; k < problem.tracks[t].second; ++k)
			problem.camera_tracks[size_t(problem.obs[k].camera)].push_back(int(t));
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
		Eigen::LevenbergMarquardt<Cost, double> lm(cost);
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

void chain_dense_tracks(const std::vector<DenseCloud> &clouds, const std::vector<CameraModel> &cameras,
			const BundleParams &params, std::vector<Track> *tracks)
{
	tracks->clear();
	if (params.chain_cell_px <= 0)
		return;
	const int n = int(cameras.size());
	// A cloud's points in a camera: pixels (project_points) and depths along its axis.
	auto project = [](const CameraModel &cam, const std::vector<cv::Point3f> &points, std::vector<cv::Point2d> *px,
			  std::vector<float> *depth) {
		const std::vector<cv::Point3d> world(points.begin(), points.end());
		*px = project_points(cam, world);
		depth->resize(world.size());
		for (size_t i = 0; i < world.size(); ++i)
			(*depth)[i] = float((cam.R * cv::Vec3d(world[i]) + cam.T)[2]);
	};
	for (size_t p = 0; p + 1 < clouds.size(); ++p) {
		const DenseCloud &A = clouds[p], &B = clouds[p + 1];
		if (A.points.empty() || B.points.empty() || A.cam_b != B.cam_a || A.cam_a < 0 || A.cam_a >= n ||
		    A.cam_b < 0 || A.cam_b >= n || B.cam_b < 0 || B.cam_b >= n)
			continue;
		const CameraModel &ca = cameras[size_t(A.cam_a)], &cm = cameras[size_t(A.cam_b)],
				  &cc = cameras[size_t(B.cam_b)];
		const cv::Size size = cm.size;
		if (size.width <= 0 || size.height <= 0)
			continue;
		// B's points in the shared camera, bucketed by 4 px cells.
		std::vector<cv::Point2d> bpx;
		std::vector<float> bz;
		project(cm, B.points, &bpx, &bz);
		const int g = 4, gw = (size.width + g - 1) / g, gh = (size.height + g - 1) / g;
		std::vector<int> start(size_t(gw * gh) + 1, 0), order(bpx.size());
		auto cell_of = [&](const cv::Point2d &q) {
			const int x = int(std::floor(q.x / g)), y = int(std::floor(q.y / g));
			return x >= 0 && y >= 0 && x < gw && y < gh ? y * gw + x : -1;
		};
		for (const cv::Point2d &q : bpx) {
			const int c = cell_of(q);
			if (c >= 0)
				start[size_t(c) + 1]++;
		}
		for (size_t c = 0; c + 1 < start.size(); ++c)
			start[c + 1] += start[c];
		{
			std::vector<int> fill(start.begin(), start.end() - 1);
			for (size_t i = 0; i < bpx.size(); ++i) {
				const int c = cell_of(bpx[i]);
				if (c >= 0)
					order[size_t(fill[size_t(c)]++)] = int(i);
			}
		}
		// A's most confident point per chain cell of the shared camera.
		std::vector<cv::Point2d> apx;
		std::vector<float> az;
		project(cm, A.points, &apx, &az);
		const int s = params.chain_cell_px, sw = (size.width + s - 1) / s, sh = (size.height + s - 1) / s;
		std::vector<int> best(size_t(sw * sh), -1);
		for (size_t i = 0; i < apx.size(); ++i) {
			const int x = int(std::floor(apx[i].x / s)), y = int(std::floor(apx[i].y / s));
			if (x < 0 || y < 0 || x >= sw || y >= sh)
				continue;
			int &b = best[size_t(y * sw + x)];
			const float conf = i < A.confidence.size() ? A.confidence[i] : 0.f;
			if (b < 0 || conf > (size_t(b) < A.confidence.size() ? A.confidence[size_t(b)] : 0.f))
				b = int(i);
		}
		std::vector<int> kept;
		std::vector<cv::Point2d> kept_px;
		std::vector<double> kept_z;
		for (int i : best) {
			if (i < 0)
				continue;
			const cv::Point2d u = apx[size_t(i)];
			// B's surface along u's ray: a plane z = a + b dx + c dy fitted to its points within 2 g.
			Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
			Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
			std::vector<std::tuple<double, double, double>> near;
			const int cx = int(u.x / g), cy = int(u.y / g);
			for (int y = cy - 2; y <= cy + 2; ++y)
				for (int x = cx - 2; x <= cx + 2; ++x) {
					if (x < 0 || y < 0 || x >= gw || y >= gh)
						continue;
					const int c = y * gw + x;
					for (int k = start[size_t(c)]; k < start[size_t(c) + 1]; ++k) {
						const int j = order[size_t(k)];
						const double dx = bpx[size_t(j)].x - u.x, dy = bpx[size_t(j)].y - u.y;
						if (dx * dx + dy * dy > 4.0 * g * g)
							continue;
						const Eigen::Vector3d row(1, dx, dy);
						H += row * row.transpose();
						rhs += row * double(bz[size_t(j)]);
						near.emplace_back(dx, dy, double(bz[size_t(j)]));
					}
				}
			if (near.size() < 6)
				continue;
			Eigen::LDLT<Eigen::Matrix3d> ldlt(H);
			if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-9))
				continue;
			const Eigen::Vector3d plane = ldlt.solve(rhs);
			double ss = 0;
			for (const auto &[dx, dy, z] : near) {
				const double e = z - (plane[0] + plane[1] * dx + plane[2] * dy);
				ss += e * e;
			}
			const double zb = plane[0];
			if (!(std::sqrt(ss / double(near.size())) <= params.chain_fit_mm) ||
			    !(std::fabs(zb - double(az[size_t(i)])) <= params.chain_gap_mm) || !(zb > 0))
				continue;
			kept.push_back(i);
			kept_px.push_back(u);
			kept_z.push_back(zb);
		}
		if (kept.empty())
			continue;
		// B's surface point on each kept pixel's ray, seen by camera p+2; A's point seen by camera p.
		std::vector<cv::Point2d> rays;
		cv::undistortPoints(kept_px, rays, cm.K, cm.dist);
		std::vector<cv::Point3d> on_b(kept.size()), on_a(kept.size());
		for (size_t k = 0; k < kept.size(); ++k) {
			const double z = kept_z[k];
			on_b[k] = cv::Point3d(cm.R.t() * (cv::Vec3d(rays[k].x * z, rays[k].y * z, z) - cm.T));
			on_a[k] = cv::Point3d(A.points[size_t(kept[k])]);
		}
		const std::vector<cv::Point2d> uc = project_points(cc, on_b), ua = project_points(ca, on_a);
		auto inside = [](const cv::Point2d &q, const cv::Size &sz) {
			return q.x >= 0 && q.y >= 0 && q.x < sz.width && q.y < sz.height;
		};
		std::vector<Track> junction;
		for (size_t k = 0; k < kept.size(); ++k)
			if (inside(uc[k], cc.size) && inside(ua[k], ca.size))
				junction.push_back({{A.cam_a, A.cam_b, B.cam_b}, {ua[k], kept_px[k], uc[k]}});
		// A handful of tracks would let one mismatch set the pairs' relative depth.
		if (int(junction.size()) >= params.chain_min_tracks)
			tracks->insert(tracks->end(), junction.begin(), junction.end());
	}
}

void retriangulate_clouds(const std::vector<CameraModel> &before, const std::vector<CameraModel> &after,
			  std::vector<DenseCloud> *clouds)
{
	const int n = int(std::min(before.size(), after.size()));
	for (DenseCloud &cloud : *clouds) {
		if (cloud.cam_a < 0 || cloud.cam_a >= n || cloud.cam_b < 0 || cloud.cam_b >= n)
			continue;
		const CameraModel &a0 = before[size_t(cloud.cam_a)], &b0 = before[size_t(cloud.cam_b)];
		const CameraModel &a1 = after[size_t(cloud.cam_a)], &b1 = after[size_t(cloud.cam_b)];
		const cv::Vec3d ca = a1.centre(), cb = b1.centre();
		// The intrinsics do not change, so a point's ray in camera coordinates is the same before
		// and after: turned into the world by the new rotation, from the new centre. The two rays
		// nearly meet (the cameras moved by tenths of a pixel): their midpoint.
		const cv::Matx33d ra = a1.R.t() * a0.R, rb = b1.R.t() * b0.R;
		const cv::Vec3d ca0 = a0.centre(), cb0 = b0.centre();
		cv::parallel_for_(cv::Range(0, int(cloud.points.size())), [&](const cv::Range &range) {
			for (int i = range.start; i < range.end; ++i) {
				cv::Point3f &P = cloud.points[size_t(i)];
				const cv::Vec3d X(P.x, P.y, P.z);
				const cv::Vec3d da = ra * (X - ca0), db = rb * (X - cb0);
				const cv::Vec3d w = ca - cb;
				const double aa = da.dot(da), ab = da.dot(db), bb = db.dot(db), aw = da.dot(w), bw = db.dot(w);
				const double den = aa * bb - ab * ab;
				if (!(den > 1e-12 * aa * bb))
					continue;
				const double sa = (ab * bw - bb * aw) / den, sb = (aa * bw - ab * aw) / den;
				const cv::Vec3d M = 0.5 * ((ca + sa * da) + (cb + sb * db));
				P = cv::Point3f(float(M[0]), float(M[1]), float(M[2]));
			}
		});
	}
}

} // namespace facescan::recon
