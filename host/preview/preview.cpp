#include "preview/preview.hpp"

#include "raycast/raycast.hpp"

#include <algorithm>
#include <cmath>

namespace facescan::preview {

namespace {

const cv::Vec3b kBackground(0x28, 0x24, 0x20); // BGR of the viewer's #202428

cv::Vec3b sample(const cv::Mat &tex, double u, double v)
{
	// recon's UVs: v runs down the image; bilinear over pixel centres, clamped at the edges.
	const double x = std::clamp(u * tex.cols - 0.5, 0.0, double(tex.cols - 1));
	const double y = std::clamp(v * tex.rows - 0.5, 0.0, double(tex.rows - 1));
	const int x0 = int(x), y0 = int(y), x1 = std::min(x0 + 1, tex.cols - 1), y1 = std::min(y0 + 1, tex.rows - 1);
	const double fx = x - x0, fy = y - y0;
	cv::Vec3d c = cv::Vec3d(tex.at<cv::Vec3b>(y0, x0)) * (1 - fx) * (1 - fy) +
		      cv::Vec3d(tex.at<cv::Vec3b>(y0, x1)) * fx * (1 - fy) +
		      cv::Vec3d(tex.at<cv::Vec3b>(y1, x0)) * (1 - fx) * fy + cv::Vec3d(tex.at<cv::Vec3b>(y1, x1)) * fx * fy;
	return cv::Vec3b(cv::saturate_cast<uint8_t>(c[0]), cv::saturate_cast<uint8_t>(c[1]),
			 cv::saturate_cast<uint8_t>(c[2]));
}

} // namespace

Camera frame_mesh(const recon::Mesh &mesh, double azimuth_deg, int width, int height, double fov_y_deg)
{
	cv::Vec3d lo(1e30, 1e30, 1e30), hi(-1e30, -1e30, -1e30);
	for (const cv::Point3f &p : mesh.positions)
		for (int k = 0; k < 3; ++k) {
			const double v = k == 0 ? p.x : k == 1 ? p.y : p.z;
			lo[k] = std::min(lo[k], v);
			hi[k] = std::max(hi[k], v);
		}
	Camera c;
	c.width = width;
	c.height = height;
	c.fov_y_deg = fov_y_deg;
	if (mesh.positions.empty())
		return c;
	c.target = (lo + hi) * 0.5;
	const double radius = cv::norm(hi - lo) * 0.5;
	const double dist = radius / std::sin(fov_y_deg * CV_PI / 360.0);
	const double az = azimuth_deg * CV_PI / 180.0;
	c.eye = c.target + dist * cv::Vec3d(std::sin(az), 0, std::cos(az));
	return c;
}

namespace {

Status build_tracer(const recon::Mesh &mesh, raycast::Tracer *tracer)
{
	if (mesh.positions.empty() || mesh.triangles.empty())
		return Status::error(-EINVAL, "preview: empty mesh");
	std::vector<cv::Vec3f> vertices;
	vertices.reserve(mesh.positions.size());
	for (const cv::Point3f &p : mesh.positions)
		vertices.emplace_back(p.x, p.y, p.z);
	return tracer->build({{&vertices, &mesh.triangles}});
}

// One view through an already built tracer (the thumbnail's three views share one BVH).
Status render_traced(const raycast::Tracer &tracer, const recon::Mesh &mesh, const Camera &cam, cv::Mat *ret_bgr,
		     cv::Mat *ret_mask)
{
	if (cam.width <= 0 || cam.height <= 0 || cam.width > 8192 || cam.height > 8192)
		return Status::error(-EINVAL, "preview: image size out of range");
	const cv::Vec3d fwd = cv::normalize(cam.target - cam.eye);
	const cv::Vec3d right = cv::normalize(fwd.cross(cv::Vec3d(0, 1, 0)));
	const cv::Vec3d up = right.cross(fwd);
	const double t = std::tan(cam.fov_y_deg * CV_PI / 360.0), aspect = double(cam.width) / cam.height;
	const bool textured = !mesh.texture.empty() && mesh.uvs.size() == mesh.positions.size();
	const bool coloured = !textured && mesh.colours.size() == mesh.positions.size();
	cv::Mat bgr(cam.height, cam.width, CV_8UC3, cv::Scalar(kBackground[0], kBackground[1], kBackground[2]));
	cv::Mat mask(cam.height, cam.width, CV_8U, cv::Scalar(0));
	cv::parallel_for_(cv::Range(0, cam.height), [&](const cv::Range &rows) {
		for (int j = rows.start; j < rows.end; ++j)
			for (int i = 0; i < cam.width; ++i) {
				const double x = (2.0 * (i + 0.5) / cam.width - 1.0) * t * aspect;
				const double y = (1.0 - 2.0 * (j + 0.5) / cam.height) * t;
				const cv::Vec3d dir = cv::normalize(fwd + x * right + y * up);
				const raycast::Hit h = tracer.intersect(cam.eye, dir);
				if (h.surface < 0)
					continue;
				mask.at<uint8_t>(j, i) = 255;
				const cv::Vec3i &tri = mesh.triangles[size_t(h.triangle)];
				const cv::Point3f &a = mesh.positions[size_t(tri[0])], &b = mesh.positions[size_t(tri[1])],
						  &c = mesh.positions[size_t(tri[2])];
				const cv::Point3f cr = (b - a).cross(c - a);
				const cv::Vec3d n = cv::normalize(cv::Vec3d(cr.x, cr.y, cr.z));
				const double shade = 0.35 + 0.65 * std::fabs(n.dot(dir)); // headlight, both sides
				const double w0 = 1.0 - h.u - h.v;
				cv::Vec3d albedo(170, 180, 200);
				if (textured) {
					const cv::Point2f &ua = mesh.uvs[size_t(tri[0])], &ub = mesh.uvs[size_t(tri[1])],
							  &uc = mesh.uvs[size_t(tri[2])];
					albedo = cv::Vec3d(sample(mesh.texture, w0 * ua.x + h.u * ub.x + h.v * uc.x,
								  w0 * ua.y + h.u * ub.y + h.v * uc.y));
				} else if (coloured) {
					albedo = w0 * cv::Vec3d(mesh.colours[size_t(tri[0])]) +
						 h.u * cv::Vec3d(mesh.colours[size_t(tri[1])]) +
						 h.v * cv::Vec3d(mesh.colours[size_t(tri[2])]);
				}
				const cv::Vec3d out = albedo * shade;
				bgr.at<cv::Vec3b>(j, i) = cv::Vec3b(cv::saturate_cast<uint8_t>(out[0]),
								    cv::saturate_cast<uint8_t>(out[1]),
								    cv::saturate_cast<uint8_t>(out[2]));
			}
	});
	if (ret_bgr)
		*ret_bgr = bgr;
	if (ret_mask)
		*ret_mask = mask;
	return {};
}

} // namespace

Status render(const recon::Mesh &mesh, const Camera &cam, cv::Mat *ret_bgr, cv::Mat *ret_mask)
{
	raycast::Tracer tracer;
	Status s = build_tracer(mesh, &tracer);
	if (!s.ok())
		return s;
	return render_traced(tracer, mesh, cam, ret_bgr, ret_mask);
}

Status thumbnail(const recon::Mesh &mesh, int view_width, int view_height, cv::Mat *ret_bgr)
{
	raycast::Tracer tracer;
	Status s = build_tracer(mesh, &tracer);
	if (!s.ok())
		return s;
	cv::Mat out(view_height, 3 * view_width, CV_8UC3);
	const double azimuths[3] = {-45, 0, 45};
	for (int k = 0; k < 3; ++k) {
		cv::Mat view;
		s = render_traced(tracer, mesh, frame_mesh(mesh, azimuths[k], view_width, view_height), &view, nullptr);
		if (!s.ok())
			return s;
		view.copyTo(out(cv::Rect(k * view_width, 0, view_width, view_height)));
	}
	*ret_bgr = out;
	return {};
}

} // namespace facescan::preview
