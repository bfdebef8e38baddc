// Rig calibration: per-camera intrinsics (calibrateCamera), consecutive pairs chained into one
// frame (stereoCalibrate with the intrinsics fixed), then a joint Levenberg–Marquardt refinement
// of every intrinsic, every camera pose and every board pose over all corner observations.
// The refinement's Jacobians come from cv::projectPoints and cv::composeRT, as inside
// cv::stereoCalibrate; the normal equations are small and dense (Eigen).
#include "calib/calib.hpp"

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>

#include <cmath>
#include <cstdio>
#include <map>

namespace facescan::calib {

namespace {

constexpr int kIntrinsics = 9; // fx fy cx cy k1 k2 p1 p2 k3
constexpr int kPose = 6;       // rvec, tvec

struct Intrinsics {
	cv::Matx33d K;
	cv::Vec<double, 5> dist;
};

struct Rigid {
	cv::Vec3d r, t; // x' = R(r) x + t
};

std::string view_name(size_t pose, size_t cam)
{
	return "pose " + std::to_string(pose) + " camera " + std::to_string(cam);
}

// Corner ids both views share, with their object points and both image points.
void common_corners(const BoardView &a, const BoardView &b, std::vector<cv::Point3f> *obj,
		    std::vector<cv::Point2f> *pa, std::vector<cv::Point2f> *pb)
{
	size_t i = 0, j = 0;
	while (i < a.ids.size() && j < b.ids.size()) {
		if (a.ids[i] < b.ids[j]) {
			i++;
		} else if (b.ids[j] < a.ids[i]) {
			j++;
		} else {
			obj->push_back(a.object_points[i]);
			pa->push_back(a.image_points[i]);
			pb->push_back(b.image_points[j]);
			i++;
			j++;
		}
	}
}

// The joint refinement. Parameters: per camera 9 intrinsics, per camera except 0 its pose
// (world → camera), per board pose its pose (board → world).
class Refinement {
public:
	struct Obs {
		int cam, pose;
		const BoardView *view;
	};

	Refinement(int cams, int poses, std::vector<Obs> obs) : cams_(cams), poses_(poses), obs_(std::move(obs))
	{
		x_ = Eigen::VectorXd::Zero(cams_ * kIntrinsics + (cams_ - 1) * kPose + poses_ * kPose);
	}

	int intr_index(int cam) const { return cam * kIntrinsics; }
	int cam_index(int cam) const { return cams_ * kIntrinsics + (cam - 1) * kPose; }
	int pose_index(int pose) const { return cams_ * kIntrinsics + (cams_ - 1) * kPose + pose * kPose; }

	void set_intrinsics(int cam, const Intrinsics &in)
	{
		double *p = &x_[intr_index(cam)];
		p[0] = in.K(0, 0), p[1] = in.K(1, 1), p[2] = in.K(0, 2), p[3] = in.K(1, 2);
		for (int k = 0; k < 5; k++)
			p[4 + k] = in.dist[k];
	}
	Intrinsics intrinsics(int cam) const
	{
		const double *p = &x_[intr_index(cam)];
		Intrinsics in;
		in.K = cv::Matx33d(p[0], 0, p[2], 0, p[1], p[3], 0, 0, 1);
		for (int k = 0; k < 5; k++)
			in.dist[k] = p[4 + k];
		return in;
	}
	void set_rigid(int at, const Rigid &g)
	{
		for (int k = 0; k < 3; k++)
			x_[at + k] = g.r[k], x_[at + 3 + k] = g.t[k];
	}
	Rigid rigid(const Eigen::VectorXd &x, int at) const
	{
		return {cv::Vec3d(x[at], x[at + 1], x[at + 2]), cv::Vec3d(x[at + 3], x[at + 4], x[at + 5])};
	}
	Rigid camera(int cam) const { return cam == 0 ? Rigid{} : rigid(x_, cam_index(cam)); }
	Rigid board(int pose) const { return rigid(x_, pose_index(pose)); }
	void set_camera(int cam, const Rigid &g) { set_rigid(cam_index(cam), g); }
	void set_board(int pose, const Rigid &g) { set_rigid(pose_index(pose), g); }

	/// Squared residual sums per observation at x (no Jacobian).
	std::vector<double> costs(const Eigen::VectorXd &x) const
	{
		std::vector<double> out(obs_.size());
		for (size_t o = 0; o < obs_.size(); o++)
			out[o] = observe(x, obs_[o], nullptr, nullptr);
		return out;
	}

	/// Runs Levenberg–Marquardt; returns the iterations taken, or -1 if it diverged.
	int run(int max_iterations)
	{
		const int n = int(x_.size());
		double cost = total(costs(x_));
		double lambda = 1e-3;
		int it = 0;
		for (; it < max_iterations; it++) {
			Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
			Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
			for (const Obs &o : obs_)
				observe(x_, o, &A, &g);
			bool improved = false;
			while (lambda < 1e12) {
				Eigen::MatrixXd M = A;
				for (int k = 0; k < n; k++)
					M(k, k) += lambda * std::max(A(k, k), 1e-9);
				const Eigen::VectorXd dx = M.ldlt().solve(-g);
				const Eigen::VectorXd x_new = x_ + dx;
				const double c = total(costs(x_new));
				if (std::isfinite(c) && c < cost) {
					const double gain = cost - c;
					x_ = x_new;
					lambda = std::max(lambda / 10, 1e-12);
					improved = true;
					if (gain < 1e-12 * cost || dx.norm() < 1e-12 * (x_.norm() + 1e-12)) {
						cost = c;
						return it + 1;
					}
					cost = c;
					break;
				}
				lambda *= 10;
			}
			if (!improved)
				break; // no step lowers the cost: converged to the precision of doubles
		}
		return std::isfinite(cost) ? it : -1;
	}

	const std::vector<Obs> &observations() const { return obs_; }
	const Eigen::VectorXd &x() const { return x_; }

private:
	static double total(const std::vector<double> &v)
	{
		double s = 0;
		for (double c : v)
			s += c;
		return s;
	}

	// Projects one observation's corners; returns the squared residual sum. With A and g, adds
	// its J^T J and J^T r to them.
	double observe(const Eigen::VectorXd &x, const Obs &o, Eigen::MatrixXd *A, Eigen::VectorXd *g) const
	{
		const Rigid b = rigid(x, pose_index(o.pose));
		const Rigid c = o.cam == 0 ? Rigid{} : rigid(x, cam_index(o.cam));
		cv::Mat r3, t3, dr3dr1, dr3dt1, dr3dr2, dr3dt2, dt3dr1, dt3dt1, dt3dr2, dt3dt2;
		cv::composeRT(b.r, b.t, c.r, c.t, r3, t3, dr3dr1, dr3dt1, dr3dr2, dr3dt2, dt3dr1, dt3dt1,
			      dt3dr2, dt3dt2);
		const double *p = &x[intr_index(o.cam)];
		const cv::Matx33d K(p[0], 0, p[2], 0, p[1], p[3], 0, 0, 1);
		const cv::Vec<double, 5> dist(p[4], p[5], p[6], p[7], p[8]);
		std::vector<cv::Point2d> proj;
		cv::Mat J;
		std::vector<cv::Point3d> obj(o.view->object_points.begin(), o.view->object_points.end());
		if (A)
			cv::projectPoints(obj, r3, t3, K, dist, proj, J);
		else
			cv::projectPoints(obj, r3, t3, K, dist, proj);
		const size_t m = proj.size();
		Eigen::VectorXd r(2 * m);
		for (size_t i = 0; i < m; i++) {
			r[2 * i] = proj[i].x - o.view->image_points[i].x;
			r[2 * i + 1] = proj[i].y - o.view->image_points[i].y;
		}
		if (A) {
			// Columns: the camera's intrinsics, its pose (cams > 0), the board pose.
			const bool moving = o.cam != 0;
			const int cols = kIntrinsics + (moving ? kPose : 0) + kPose;
			Eigen::MatrixXd Jl(2 * m, cols);
			auto mat = [](const cv::Mat &mm) {
				Eigen::Matrix3d e;
				for (int i = 0; i < 3; i++)
					for (int j = 0; j < 3; j++)
						e(i, j) = mm.at<double>(i, j);
				return e;
			};
			Eigen::Matrix<double, 6, 6> d_board, d_cam; // d(r3,t3)/d(r,t)
			d_board << mat(dr3dr1), mat(dr3dt1), mat(dt3dr1), mat(dt3dt1);
			d_cam << mat(dr3dr2), mat(dr3dt2), mat(dt3dr2), mat(dt3dt2);
			for (size_t i = 0; i < 2 * m; i++) {
				const double *row = J.ptr<double>(int(i));
				Eigen::Matrix<double, 1, 6> d_rt;
				for (int k = 0; k < 6; k++)
					d_rt[k] = row[k];
				for (int k = 0; k < kIntrinsics; k++)
					Jl(Eigen::Index(i), k) = row[6 + k];
				int at = kIntrinsics;
				if (moving) {
					Jl.block<1, 6>(Eigen::Index(i), at) = d_rt * d_cam;
					at += kPose;
				}
				Jl.block<1, 6>(Eigen::Index(i), at) = d_rt * d_board;
			}
			const Eigen::MatrixXd JtJ = Jl.transpose() * Jl;
			const Eigen::VectorXd Jtr = Jl.transpose() * r;
			int idx[3] = {intr_index(o.cam), moving ? cam_index(o.cam) : -1, pose_index(o.pose)};
			int len[3] = {kIntrinsics, moving ? kPose : 0, kPose};
			int off[3] = {0, kIntrinsics, kIntrinsics + (moving ? kPose : 0)};
			for (int a = 0; a < 3; a++) {
				if (!len[a])
					continue;
				g->segment(idx[a], len[a]) += Jtr.segment(off[a], len[a]);
				for (int bb = 0; bb < 3; bb++)
					if (len[bb])
						A->block(idx[a], idx[bb], len[a], len[bb]) +=
							JtJ.block(off[a], off[bb], len[a], len[bb]);
			}
		}
		return r.squaredNorm();
	}

	int cams_, poses_;
	std::vector<Obs> obs_;
	Eigen::VectorXd x_;
};

cv::Matx33d rotation(const cv::Vec3d &r)
{
	cv::Matx33d R;
	cv::Rodrigues(r, R);
	return R;
}

cv::Vec3d rvec(const cv::Matx33d &R)
{
	cv::Vec3d r;
	cv::Rodrigues(R, r);
	return r;
}

} // namespace

namespace {

Status calibrate(const std::vector<std::vector<BoardView>> &views, const std::vector<cv::Size> &sizes,
		 const CalibParams &params, Calibration *ret_calibration, RigReport *ret_report)
{
	const size_t cams = sizes.size(), poses = views.size();
	if (cams < 1)
		return Status::error(EINVAL, "no cameras");
	for (size_t p = 0; p < poses; p++)
		if (views[p].size() != cams)
			return Status::error(EINVAL, "pose " + std::to_string(p) + " has " +
							     std::to_string(views[p].size()) +
							     " views for " + std::to_string(cams) +
							     " cameras");
	RigReport report;
	report.cameras.resize(cams);
	// usable[p][c]: the view is found and survived the per-camera check.
	std::vector<std::vector<bool>> usable(poses, std::vector<bool>(cams, false));
	for (size_t p = 0; p < poses; p++)
		for (size_t c = 0; c < cams; c++)
			usable[p][c] = views[p][c].found && views[p][c].image_points.size() >= 4 &&
				       views[p][c].image_points.size() == views[p][c].object_points.size();

	// 1. Intrinsics per camera.
	std::vector<Intrinsics> intr(cams);
	for (size_t c = 0; c < cams; c++) {
		for (int pass = 0; pass < 2; pass++) {
			std::vector<std::vector<cv::Point3f>> obj;
			std::vector<std::vector<cv::Point2f>> img;
			std::vector<size_t> which;
			for (size_t p = 0; p < poses; p++)
				if (usable[p][c]) {
					obj.push_back(views[p][c].object_points);
					img.push_back(views[p][c].image_points);
					which.push_back(p);
				}
			if (int(obj.size()) < params.min_views_per_camera)
				return Status::error(EINVAL, "camera " + std::to_string(c) + ": " +
								     std::to_string(obj.size()) +
								     " usable board views, need at least " +
								     std::to_string(params.min_views_per_camera));
			cv::Mat K, D, std_in, std_ex, per_view;
			std::vector<cv::Mat> rv, tv;
			const double rms = cv::calibrateCamera(
				obj, img, sizes[c], K, D, rv, tv, std_in, std_ex, per_view, 0,
				cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100,
						 1e-12));
			if (!std::isfinite(rms))
				return Status::error(EDOM, "camera " + std::to_string(c) +
								   ": intrinsic calibration diverged");
			intr[c].K = cv::Matx33d(K);
			for (int k = 0; k < 5; k++)
				intr[c].dist[k] = D.at<double>(k);
			report.cameras[c].intrinsic_rms_px = rms;
			report.cameras[c].views = int(obj.size());
			bool dropped = false;
			for (size_t v = 0; v < which.size() && pass == 0; v++) {
				const double e = per_view.at<double>(int(v));
				if (e > params.max_view_rms_px) {
					usable[which[v]][c] = false;
					dropped = true;
					char buf[160];
					std::snprintf(buf, sizeof buf,
						      "%s: reprojection RMS %.2f px > %.2f px after the "
						      "camera's own calibration (misdetected corners?)",
						      view_name(which[v], c).c_str(), e,
						      params.max_view_rms_px);
					report.dropped.push_back(buf);
				}
			}
			if (!dropped)
				break;
		}
	}

	// 2. Consecutive pairs, chained from camera 0.
	std::vector<Rigid> cam_pose(cams); // world (= camera 0) → camera
	for (size_t c = 0; c + 1 < cams; c++) {
		std::vector<std::vector<cv::Point3f>> obj;
		std::vector<std::vector<cv::Point2f>> ia, ib;
		for (size_t p = 0; p < poses; p++) {
			if (!usable[p][c] || !usable[p][c + 1])
				continue;
			std::vector<cv::Point3f> o;
			std::vector<cv::Point2f> a, b;
			common_corners(views[p][c], views[p][c + 1], &o, &a, &b);
			if (o.size() < 4)
				continue;
			obj.push_back(std::move(o));
			ia.push_back(std::move(a));
			ib.push_back(std::move(b));
		}
		PairReport pr;
		pr.cam_a = int(c);
		pr.cam_b = int(c + 1);
		pr.views = int(obj.size());
		if (pr.views < params.min_views_per_pair)
			return Status::error(EINVAL, "cameras " + std::to_string(c) + " and " +
							     std::to_string(c + 1) + " saw the board together in " +
							     std::to_string(pr.views) +
							     " poses, need at least " +
							     std::to_string(params.min_views_per_pair));
		cv::Mat Ka(intr[c].K), Da(intr[c].dist), Kb(intr[c + 1].K), Db(intr[c + 1].dist);
		cv::Mat R, T, E, F;
		pr.chain_rms_px = cv::stereoCalibrate(
			obj, ia, ib, Ka, Da, Kb, Db, sizes[c], R, T, E, F, cv::CALIB_FIX_INTRINSIC,
			cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
		if (!std::isfinite(pr.chain_rms_px))
			return Status::error(EDOM, "stereo calibration of cameras " + std::to_string(c) +
							   " and " + std::to_string(c + 1) + " diverged");
		const cv::Matx33d Rab(R), Rw = rotation(cam_pose[c].r);
		const cv::Vec3d Tab(T);
		cam_pose[c + 1].r = rvec(Rab * Rw);
		cam_pose[c + 1].t = Rab * cam_pose[c].t + Tab;
		report.pairs.push_back(pr);
	}

	// 3. Board poses in the world: from the camera that sees the most corners.
	std::vector<int> pose_slot(poses, -1);
	int used_poses = 0;
	std::vector<Rigid> boards;
	std::vector<Refinement::Obs> obs;
	for (size_t p = 0; p < poses; p++) {
		int best = -1;
		for (size_t c = 0; c < cams; c++)
			if (usable[p][c] && (best < 0 || views[p][c].ids.size() > views[p][size_t(best)].ids.size()))
				best = int(c);
		if (best < 0)
			continue;
		const BoardView &v = views[p][size_t(best)];
		cv::Vec3d r, t;
		cv::solvePnP(v.object_points, v.image_points, intr[size_t(best)].K, intr[size_t(best)].dist, r, t);
		// board → camera `best` → world: x_w = Rc^T (Rb x + tb - tc).
		const cv::Matx33d Rc = rotation(cam_pose[size_t(best)].r), Rb = rotation(r);
		boards.push_back({rvec(Rc.t() * Rb), Rc.t() * (t - cam_pose[size_t(best)].t)});
		pose_slot[p] = used_poses++;
		for (size_t c = 0; c < cams; c++)
			if (usable[p][c])
				obs.push_back({int(c), pose_slot[p], &views[p][c]});
	}
	if (params.origin_pose >= 0 &&
	    (size_t(params.origin_pose) >= poses || pose_slot[size_t(params.origin_pose)] < 0))
		return Status::error(EINVAL, "origin pose " + std::to_string(params.origin_pose) +
						     ": no camera saw the board in that pose");

	// 4. Joint refinement.
	Refinement lm(int(cams), used_poses, obs);
	for (size_t c = 0; c < cams; c++) {
		lm.set_intrinsics(int(c), intr[c]);
		if (c > 0)
			lm.set_camera(int(c), cam_pose[c]);
	}
	for (int b = 0; b < used_poses; b++)
		lm.set_board(b, boards[size_t(b)]);
	report.iterations = lm.run(params.max_iterations);
	if (report.iterations < 0)
		return Status::error(EDOM, "joint refinement diverged");

	// 5. Report.
	const std::vector<double> cost = lm.costs(lm.x());
	std::vector<double> cam_sum(cams, 0);
	std::vector<size_t> cam_n(cams, 0);
	std::map<std::pair<int, int>, double> per_obs; // (pose slot, cam) → squared sum
	std::map<std::pair<int, int>, size_t> per_obs_n;
	double all = 0;
	size_t all_n = 0;
	for (size_t o = 0; o < obs.size(); o++) {
		const size_t n = obs[o].view->image_points.size();
		cam_sum[size_t(obs[o].cam)] += cost[o];
		cam_n[size_t(obs[o].cam)] += n;
		per_obs[{obs[o].pose, obs[o].cam}] = cost[o];
		per_obs_n[{obs[o].pose, obs[o].cam}] = n;
		all += cost[o];
		all_n += n;
	}
	for (size_t c = 0; c < cams; c++)
		report.cameras[c].final_rms_px = cam_n[c] ? std::sqrt(cam_sum[c] / double(cam_n[c])) : 0;
	for (PairReport &pr : report.pairs) {
		double s = 0;
		size_t n = 0;
		for (int b = 0; b < used_poses; b++) {
			auto a = per_obs.find({b, pr.cam_a}), bb = per_obs.find({b, pr.cam_b});
			if (a == per_obs.end() || bb == per_obs.end())
				continue;
			s += a->second + bb->second;
			n += per_obs_n[{b, pr.cam_a}] + per_obs_n[{b, pr.cam_b}];
		}
		// stereoCalibrate's figure: both cameras' squared errors over 2 × corners per camera.
		pr.final_rms_px = n ? std::sqrt(s / double(n)) : 0;
	}
	report.final_rms_px = all_n ? std::sqrt(all / double(all_n)) : 0;
	report.observations = int(all_n);

	// 6. The calibration, in the chosen world frame.
	cv::Matx33d Rw = cv::Matx33d::eye(); // old world → new world
	cv::Vec3d tw(0, 0, 0);
	if (params.origin_pose >= 0) {
		const Rigid b = lm.board(pose_slot[size_t(params.origin_pose)]);
		// new world = board frame: x_board = Rb^T (x_w - tb).
		const cv::Matx33d Rb = rotation(b.r);
		Rw = Rb.t();
		tw = -(Rb.t() * b.t);
		report.world_frame = "the board in pose " + std::to_string(params.origin_pose) +
				     ": origin at its inner corner 0, x along its rows, y along its "
				     "columns, z into the board; mm";
	} else {
		report.world_frame = "camera 0: origin at its centre, x right, y down, z along its "
				     "optical axis; mm";
	}
	Calibration cal;
	for (size_t c = 0; c < cams; c++) {
		const Intrinsics in = lm.intrinsics(int(c));
		const Rigid g = lm.camera(int(c));
		CameraModel m;
		m.K = in.K;
		m.dist = in.dist;
		// x_cam = Rc x_old + tc, x_old = Rw^T (x_new - tw).
		const cv::Matx33d Rc = rotation(g.r);
		m.R = Rc * Rw.t();
		m.T = g.t - m.R * tw;
		m.size = sizes[c];
		cal.cameras.push_back(m);
	}
	*ret_calibration = std::move(cal);
	*ret_report = std::move(report);
	return Status();
}

} // namespace

Status calibrate_rig(const std::vector<std::vector<BoardView>> &views,
		     const std::vector<cv::Size> &sizes, const CalibParams &params,
		     Calibration *ret_calibration, RigReport *ret_report)
{
	try {
		return calibrate(views, sizes, params, ret_calibration, ret_report);
	} catch (const cv::Exception &e) {
		// OpenCV rejects degenerate data (e.g. all views of one camera coplanar and parallel).
		return Status::error(EDOM, std::string("calibration failed in OpenCV: ") + e.what());
	}
}

} // namespace facescan::calib
