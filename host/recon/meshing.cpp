// Stage 7: meshing. See meshing.hpp.
#include "recon/meshing.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

namespace facescan::recon {

std::vector<cv::Vec3i> delaunay_2d(const std::vector<cv::Point2d> &sites)
{
	std::vector<cv::Vec3i> out;
	if (sites.size() < 3)
		return out;
	double x0 = sites[0].x, y0 = sites[0].y, x1 = x0, y1 = y0;
	for (const cv::Point2d &p : sites) {
		x0 = std::min(x0, p.x);
		y0 = std::min(y0, p.y);
		x1 = std::max(x1, p.x);
		y1 = std::max(y1, p.y);
	}
	// Subdiv2D works in float: shift and scale the sites into a well-conditioned box.
	const double span = std::max({x1 - x0, y1 - y0, 1e-9});
	const double s = 1000.0 / span;
	cv::Subdiv2D subdiv(cv::Rect(-10, -10, 1021, 1021));
	std::map<std::pair<float, float>, int> index;
	std::vector<cv::Point2f> fs(sites.size());
	for (size_t i = 0; i < sites.size(); ++i) {
		fs[i] = cv::Point2f(float((sites[i].x - x0) * s), float((sites[i].y - y0) * s));
		if (!std::isfinite(fs[i].x) || !std::isfinite(fs[i].y))
			continue;
		const auto key = std::make_pair(fs[i].x, fs[i].y);
		if (index.count(key))
			continue;
		index.emplace(key, int(i));
		subdiv.insert(fs[i]);
	}
	std::vector<cv::Vec6f> list;
	subdiv.getTriangleList(list);
	out.reserve(list.size());
	for (const cv::Vec6f &t : list) {
		cv::Vec3i tri;
		bool ok = true;
		for (int k = 0; k < 3 && ok; ++k) {
			auto it = index.find(std::make_pair(t[2 * k], t[2 * k + 1]));
			if (it == index.end())
				ok = false; // a corner of Subdiv2D's bounding triangle
			else
				tri[k] = it->second;
		}
		if (!ok)
			continue;
		// Counter-clockwise in the site frame.
		const cv::Point2d a = sites[size_t(tri[0])], b = sites[size_t(tri[1])], c = sites[size_t(tri[2])];
		if ((b - a).cross(c - a) < 0)
			std::swap(tri[1], tri[2]);
		out.push_back(tri);
	}
	return out;
}

std::vector<cv::Vec3i> filter_triangles(const std::vector<cv::Point3d> &points,
					const std::vector<cv::Vec3i> &tris,
					const std::vector<cv::Vec3d> &camera_centres,
					const cv::Point3d &inside, const MeshingParams &params,
					MeshingStats *ret_stats)
{
	MeshingStats stats;
	stats.delaunay = int(tris.size());
	std::vector<double> edges;
	edges.reserve(tris.size() * 3);
	for (const cv::Vec3i &t : tris)
		for (int k = 0; k < 3; ++k) {
			const int a = t[k], b = t[(k + 1) % 3];
			if (a < b) // each interior edge once (it appears as a<b in one of its two triangles)
				edges.push_back(cv::norm(points[size_t(a)] - points[size_t(b)]));
		}
	double median = 0;
	if (!edges.empty()) {
		std::nth_element(edges.begin(), edges.begin() + long(edges.size() / 2), edges.end());
		median = edges[edges.size() / 2];
	}
	stats.median_edge_mm = median;
	const double max_edge = params.max_edge_factor * median;
	const double min_cos = std::cos(params.max_grazing_deg * CV_PI / 180.0);

	std::vector<cv::Vec3i> out;
	out.reserve(tris.size());
	for (cv::Vec3i t : tris) {
		const cv::Point3d &a = points[size_t(t[0])], &b = points[size_t(t[1])], &c = points[size_t(t[2])];
		if (cv::norm(a - b) > max_edge || cv::norm(b - c) > max_edge || cv::norm(c - a) > max_edge) {
			stats.dropped_long++;
			continue;
		}
		cv::Point3d n = (b - a).cross(c - a);
		const double len = cv::norm(n);
		if (len <= 0) {
			stats.dropped_grazing++;
			continue;
		}
		n *= 1.0 / len;
		const cv::Point3d g = (a + b + c) * (1.0 / 3.0);
		double best = camera_centres.empty() ? 1.0 : 0.0;
		for (const cv::Vec3d &cc : camera_centres) {
			const cv::Point3d v = cv::Point3d(cc) - g;
			best = std::max(best, std::fabs(n.dot(v)) / cv::norm(v));
		}
		if (best < min_cos) {
			stats.dropped_grazing++;
			continue;
		}
		if (n.dot(g - inside) < 0)
			std::swap(t[1], t[2]);
		out.push_back(t);
	}
	stats.kept = int(out.size());
	if (ret_stats)
		*ret_stats = stats;
	return out;
}

Status mesh_partial(const CameraModel &cam_a, const CameraModel &cam_b, const MeshingParams &params,
		    PartialModel *model, MeshingStats *ret_stats)
{
	if (model->sources.size() != model->points.size())
		return Status::error(-EINVAL, "mesh_partial: model has " + std::to_string(model->points.size()) +
						      " points but " + std::to_string(model->sources.size()) +
						      " sources");
	std::vector<cv::Point2d> sites(model->points.size());
	for (size_t i = 0; i < sites.size(); ++i)
		sites[i] = model->sources[i].a;
	const std::vector<cv::Vec3i> tris = delaunay_2d(sites);
	// "Inside" for orientation: far behind the surface as seen from the pair's cameras.
	const cv::Vec3d ca = cam_a.centre(), cb = cam_b.centre();
	cv::Point3d centroid(0, 0, 0);
	for (const cv::Point3d &p : model->points)
		centroid += p;
	if (!model->points.empty())
		centroid *= 1.0 / double(model->points.size());
	const cv::Point3d eye = (cv::Point3d(ca) + cv::Point3d(cb)) * 0.5;
	const cv::Point3d inside = centroid + (centroid - eye) * 10.0;
	model->triangles = filter_triangles(model->points, tris, {ca, cb}, inside, params, ret_stats);
	return {};
}

} // namespace facescan::recon
