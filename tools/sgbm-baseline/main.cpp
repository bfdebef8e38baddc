// sgbm-baseline: the benchmark's reference — a stock OpenCV stereo pipeline with no decoding at
// all, as the issue that asked for the dense stage measured it: per consecutive pair, OpenCV's
// stereoRectify (without CALIB_ZERO_DISPARITY, which pushes converging views off the image), StereoSGBM in 3-way mode at half resolution over the
// disparity range of the booth's working volume, SGBM's left-right check and speckle filter,
// reprojectImageTo3D, each pair's valid pixels meshed as a grid; the three sheets are written
// side by side, not fused. `make bench` runs it on the same capture as `facescan recon` and prints
// both (docs/benchmarks.md). Not a user tool: it exists to be measured against.
//
//   sgbm-baseline CAPTURE_DIR -o OUT.drc [--scale 0.5] [--depth-range MM]
#include "capture/capture_set.hpp"
#include "mesh_io/mesh_io.hpp"
#include "recon/types.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <getopt.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace facescan;

namespace {

// The point nearest to both cameras' optical axes: where a booth's cameras look.
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

int run_pair(const cv::Mat &fa, const cv::Mat &fb, const CameraModel &a, const CameraModel &b, double scale,
	     double depth_range, recon::Mesh *mesh)
{
	const cv::Matx33d R = b.R * a.R.t();
	const cv::Vec3d T = b.T - R * a.T;
	const cv::Size size(int(a.size.width * scale), int(a.size.height * scale));
	cv::Mat R1, R2, P1, P2, Q;
	cv::stereoRectify(cv::Mat(a.K), cv::Mat(a.dist), cv::Mat(b.K), cv::Mat(b.dist), a.size, cv::Mat(R),
			  cv::Mat(T), R1, R2, P1, P2, Q, 0, -1, size);
	cv::Mat m1x, m1y, m2x, m2y, la, lb;
	cv::initUndistortRectifyMap(cv::Mat(a.K), cv::Mat(a.dist), R1, P1, size, CV_32FC1, m1x, m1y);
	cv::initUndistortRectifyMap(cv::Mat(b.K), cv::Mat(b.dist), R2, P2, size, CV_32FC1, m2x, m2y);
	cv::remap(fa, la, m1x, m1y, cv::INTER_LINEAR);
	cv::remap(fb, lb, m2x, m2y, cv::INTER_LINEAR);
	// Disparity range of the working volume: ±depth_range along the cameras' mean axis and
	// ±100 mm across it, around where the axes meet.
	const cv::Vec3d centre = axes_meet(a, b);
	cv::Vec3d axis = a.R.t() * cv::Vec3d(0, 0, 1) + b.R.t() * cv::Vec3d(0, 0, 1);
	axis *= 1.0 / cv::norm(axis);
	const cv::Vec3d side = axis.cross(cv::Vec3d(0, 1, 0)) * (1.0 / std::max(1e-9, cv::norm(axis.cross(cv::Vec3d(0, 1, 0)))));
	const cv::Vec3d up = side.cross(axis);
	double dmin = 1e9, dmax = -1e9;
	for (int k = 0; k < 27; ++k) {
		const cv::Vec3d p = centre + axis * ((k % 3 - 1) * depth_range) + side * ((k / 3 % 3 - 1) * 100.0) +
				    up * ((k / 9 - 1) * 100.0);
		const cv::Vec3d pa = a.R * p + a.T, pb = b.R * p + b.T;
		const cv::Vec3d ra = cv::Matx33d(R1) * pa, rb = cv::Matx33d(R2) * pb;
		const double xa = P1.at<double>(0, 0) * ra[0] / ra[2] + P1.at<double>(0, 2);
		const double xb = P2.at<double>(0, 0) * rb[0] / rb[2] + P2.at<double>(0, 2);
		dmin = std::min(dmin, xa - xb);
		dmax = std::max(dmax, xa - xb);
	}
	const int mind = int(std::floor(dmin));
	int nd = std::max(16, int(std::ceil((dmax - dmin) / 16)) * 16);
	const int block = 5;
	// The whole range must fit in the image (OpenCV asserts inside SGBM otherwise).
	if (mind + nd > size.width - block - 1)
		nd = ((size.width - block - 1 - mind) / 16) * 16;
	if (nd < 16 || mind < -size.width)
		return 0;
	if (getenv("SGBM_BASELINE_VERBOSE"))
		std::fprintf(stderr, "pair: disparities %d + %d\n", mind, nd);
	cv::Ptr<cv::StereoSGBM> sgbm = cv::StereoSGBM::create(mind, nd, block, 8 * 3 * block * block,
							      32 * 3 * block * block, 1, 31, 10, 100, 2,
							      cv::StereoSGBM::MODE_SGBM_3WAY);
	cv::Mat disp16, disp, xyz;
	sgbm->compute(la, lb, disp16);
	disp16.convertTo(disp, CV_32F, 1.0 / 16);
	cv::reprojectImageTo3D(disp, xyz, Q, true);
	// Grid mesh over the valid pixels (world mm); no triangle across a depth jump.
	std::vector<int> id(size_t(size.area()), -1);
	const cv::Matx33d R1t = cv::Matx33d(R1).t();
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x) {
			const float d = disp.at<float>(y, x);
			const cv::Vec3f p = xyz.at<cv::Vec3f>(y, x);
			if (d < mind || !(std::fabs(p[2]) < 5000) || p[2] <= 0)
				continue;
			const cv::Vec3d cam = R1t * cv::Vec3d(p);
			id[size_t(y * size.width + x)] = int(mesh->positions.size());
			mesh->positions.emplace_back(cv::Point3d(a.R.t() * (cam - a.T)));
		}
	auto close = [&](int i, int j) { return cv::norm(mesh->positions[size_t(i)] - mesh->positions[size_t(j)]) < 3.0; };
	for (int y = 0; y + 1 < size.height; ++y)
		for (int x = 0; x + 1 < size.width; ++x) {
			const int v00 = id[size_t(y * size.width + x)], v10 = id[size_t(y * size.width + x + 1)];
			const int v01 = id[size_t((y + 1) * size.width + x)], v11 = id[size_t((y + 1) * size.width + x + 1)];
			if (v00 >= 0 && v10 >= 0 && v11 >= 0 && close(v00, v10) && close(v10, v11) && close(v11, v00))
				mesh->triangles.emplace_back(v00, v11, v10);
			if (v00 >= 0 && v11 >= 0 && v01 >= 0 && close(v00, v11) && close(v11, v01) && close(v01, v00))
				mesh->triangles.emplace_back(v00, v01, v11);
		}
	return 0;
}

} // namespace

int main(int argc, char **argv)
{
	static const option options[] = {{"out", required_argument, nullptr, 'o'},
					 {"scale", required_argument, nullptr, 's'},
					 {"depth-range", required_argument, nullptr, 'd'},
					 {nullptr, 0, nullptr, 0}};
	std::string out;
	double scale = 0.5, depth_range = 120;
	for (int opt; (opt = getopt_long(argc, argv, "o:", options, nullptr)) != -1;) {
		if (opt == 'o')
			out = optarg;
		else if (opt == 's')
			scale = std::atof(optarg);
		else if (opt == 'd')
			depth_range = std::atof(optarg);
		else
			return 2;
	}
	if (optind + 1 != argc || out.empty() || !(scale > 0.05 && scale <= 1) || !(depth_range > 0)) {
		std::fprintf(stderr, "usage: sgbm-baseline CAPTURE_DIR -o OUT.drc [--scale S] [--depth-range MM]\n");
		return 2;
	}
	CaptureSet set;
	Status s = read_capture_set(argv[optind], &set);
	if (!s.ok()) {
		std::fprintf(stderr, "sgbm-baseline: %s\n", s.message().c_str());
		return 1;
	}
	recon::Mesh mesh;
	const std::vector<CameraModel> &cams = set.calibration.cameras;
	for (size_t p = 0; p + 1 < cams.size() && p + 1 < set.frames.size(); ++p)
		run_pair(set.frames[p], set.frames[p + 1], cams[p], cams[p + 1], scale, depth_range, &mesh);
	if (mesh.triangles.empty()) {
		std::fprintf(stderr, "sgbm-baseline: nothing matched\n");
		return 1;
	}
	s = mesh_io::write_draco(out, mesh, mesh_io::DracoOptions());
	if (!s.ok()) {
		std::fprintf(stderr, "sgbm-baseline: %s\n", s.message().c_str());
		return 1;
	}
	std::printf("sgbm-baseline: %s: %zu vertices, %zu triangles\n", out.c_str(), mesh.positions.size(),
		    mesh.triangles.size());
	return 0;
}
