// Face coverage of a rig: which face points the projectors light and the stereo pairs see, by
// ray casting against the head (no rendering).
#include "sim/internal.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

namespace facescan::sim {

namespace {
// A camera must see a point within 72 deg of its normal for stereo matching to have a chance
// (the square is foreshortened 3:1 there); a projector lights anything it faces.
constexpr double kCameraMinCos = 0.3, kProjectorMinCos = 0.1;
} // namespace

Status face_coverage(const Rig &rig, const Scene &scene, FaceCoverage *ret_coverage)
{
	Mesh head;
	Status st = make_head(scene.head, scene.skin, &head);
	if (!st.ok())
		return st;
	const std::vector<char> face = face_region(scene.head, head);
	transform_mesh(internal::head_rotation(scene.yaw_deg, scene.pitch_deg, scene.roll_deg), scene.position, &head);
	Surface surface;
	surface.mesh = head;
	Tracer tracer;
	st = build_tracer({surface}, &tracer);
	if (!st.ok())
		return st;
	const size_t n = head.vertices.size();
	// Exact visibility (a shadow ray from the point, lifted 0.05 mm off the surface) and a
	// limit on the angle: what the booth itself does, not the evaluation's z-buffer, which
	// gives up on surfaces steeper than ~60 deg to a device at its 1 mm tolerance.
	auto sees = [&](const cv::Vec3d &centre, const cv::Matx33d &K, const cv::Matx33d &R, const cv::Vec3d &T,
			const cv::Size &size, const cv::Vec<double, 5> *dist, const std::vector<cv::Point2d> &mask,
			double min_cos) {
		std::vector<char> v(n, 0);
		std::vector<cv::Point2f> poly(mask.begin(), mask.end());
		cv::parallel_for_(cv::Range(0, int(n)), [&](const cv::Range &r) {
			for (int i = r.start; i < r.end; i++) {
				const cv::Vec3d p(head.vertices[size_t(i)]), nrm(head.normals[size_t(i)]);
				cv::Vec3d to = centre - p;
				const double d = cv::norm(to);
				to *= 1.0 / d;
				if (nrm.dot(to) < min_cos)
					continue;
				const cv::Vec3d x = R * p + T;
				if (x[2] <= 0)
					continue;
				cv::Point2d u(x[0] / x[2], x[1] / x[2]);
				if (dist) {
					std::vector<cv::Point3d> obj{cv::Point3d(x[0], x[1], x[2])};
					std::vector<cv::Point2d> img;
					cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, *dist, img);
					u = img[0];
				} else {
					const cv::Vec3d k = K * cv::Vec3d(u.x, u.y, 1);
					u = cv::Point2d(k[0], k[1]);
				}
				if (u.x < -0.5 || u.y < -0.5 || u.x > size.width - 0.5 || u.y > size.height - 0.5)
					continue;
				if (!poly.empty() && cv::pointPolygonTest(poly, cv::Point2f(float(u.x), float(u.y)), false) < 0)
					continue;
				if (tracer.occluded(p + 0.05 * nrm, to, 0.01, d - 1))
					continue;
				v[size_t(i)] = 1;
			}
		});
		return v;
	};
	std::vector<std::vector<char>> cams;
	for (const SimCamera &c : rig.cameras)
		cams.push_back(sees(c.model.centre(), c.model.K, c.model.R, c.model.T, c.model.size, &c.model.dist, {},
				    kCameraMinCos));
	std::vector<int> lit(n, 0);
	for (const SimProjector &p : rig.projectors) {
		const std::vector<char> v = sees(p.centre(), p.K, p.R, p.T, p.size, nullptr, p.mask, kProjectorMinCos);
		for (size_t i = 0; i < n; i++)
			lit[i] += v[i];
	}
	FaceCoverage r;
	int n_lit = 0, n_twice = 0, n_paired = 0, n_both = 0;
	for (size_t i = 0; i < n; i++) {
		if (!face[i])
			continue;
		r.face_points++;
		bool paired = false;
		for (size_t c = 0; c + 1 < cams.size(); c++)
			paired |= cams[c][i] && cams[c + 1][i];
		n_lit += lit[i] > 0;
		n_twice += lit[i] > 1;
		n_paired += paired;
		n_both += paired && lit[i] > 0;
	}
	if (r.face_points) {
		r.lit = double(n_lit) / r.face_points;
		r.lit_twice = double(n_twice) / r.face_points;
		r.paired = double(n_paired) / r.face_points;
		r.lit_and_paired = double(n_both) / r.face_points;
	}
	*ret_coverage = r;
	return Status();
}

} // namespace facescan::sim
