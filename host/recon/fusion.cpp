// Stage 9: fusion. See fusion.hpp.
#include "recon/fusion.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <numeric>
#include <queue>
#include <unordered_map>

namespace facescan::recon {

namespace {

int64_t key(int camera, int square, int feature)
{
	return (int64_t(camera) << 40) | (int64_t(square) << 4) | int64_t(feature);
}

struct UnionFind {
	std::vector<int> parent;
	explicit UnionFind(size_t n) : parent(n)
	{
		std::iota(parent.begin(), parent.end(), 0);
	}
	int find(int x)
	{
		while (parent[size_t(x)] != x) {
			parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
			x = parent[size_t(x)];
		}
		return x;
	}
	void unite(int a, int b)
	{
		a = find(a);
		b = find(b);
		if (a != b)
			parent[size_t(std::max(a, b))] = std::min(a, b);
	}
};

} // namespace

std::vector<double> border_distances(const PartialModel &model)
{
	const size_t n = model.points.size();
	std::vector<double> dist(n, std::numeric_limits<double>::infinity());
	std::map<std::pair<int, int>, int> edge_use;
	std::vector<std::vector<int>> adj(n);
	std::vector<char> used(n, 0);
	for (const cv::Vec3i &t : model.triangles)
		for (int k = 0; k < 3; ++k) {
			const int a = t[k], b = t[(k + 1) % 3];
			used[size_t(a)] = 1;
			if (edge_use[{std::min(a, b), std::max(a, b)}]++ == 0) {
				adj[size_t(a)].push_back(b);
				adj[size_t(b)].push_back(a);
			}
		}
	using Item = std::pair<double, int>;
	std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
	for (size_t i = 0; i < n; ++i)
		if (!used[i]) {
			dist[i] = 0;
			queue.emplace(0.0, int(i));
		}
	for (const auto &[e, count] : edge_use)
		if (count == 1)
			for (int v : {e.first, e.second})
				if (dist[size_t(v)] != 0) {
					dist[size_t(v)] = 0;
					queue.emplace(0.0, v);
				}
	// Multi-source Dijkstra along the mesh edges.
	while (!queue.empty()) {
		const auto [d, v] = queue.top();
		queue.pop();
		if (d > dist[size_t(v)])
			continue;
		for (int w : adj[size_t(v)]) {
			const double nd = d + cv::norm(model.points[size_t(v)] - model.points[size_t(w)]);
			if (nd < dist[size_t(w)]) {
				dist[size_t(w)] = nd;
				queue.emplace(nd, w);
			}
		}
	}
	// A closed mesh has no border: every point is "far" from one; keep the value finite.
	for (double &d : dist)
		if (!std::isfinite(d))
			d = 1e6;
	return dist;
}

cv::Point3d blend(const std::vector<cv::Point3d> &copies, const std::vector<double> &border_mm, double floor_mm)
{
	cv::Point3d sum(0, 0, 0);
	double wsum = 0;
	for (size_t i = 0; i < copies.size(); ++i) {
		const double w = std::max(0.0, border_mm[i]) + floor_mm;
		sum += copies[i] * w;
		wsum += w;
	}
	return wsum > 0 ? sum * (1.0 / wsum) : sum;
}

std::vector<cv::Point3f> vertex_normals(const std::vector<cv::Point3f> &positions,
					const std::vector<cv::Vec3i> &triangles)
{
	std::vector<cv::Point3f> normals(positions.size(), cv::Point3f(0, 0, 0));
	for (const cv::Vec3i &t : triangles) {
		const cv::Point3f &a = positions[size_t(t[0])], &b = positions[size_t(t[1])],
				  &c = positions[size_t(t[2])];
		const cv::Point3f n = (b - a).cross(c - a); // length = 2 * area: area weighting
		for (int k = 0; k < 3; ++k)
			normals[size_t(t[k])] += n;
	}
	for (cv::Point3f &n : normals) {
		const float len = std::sqrt(n.dot(n));
		if (len > 0)
			n *= 1.0f / len;
	}
	return normals;
}

ViewFrame view_frame(const std::vector<cv::Point3d> &points, const std::vector<CameraModel> &cameras)
{
	// Centre behind the face (from the centroid, away from the cameras by the points' extent),
	// axes from the cameras' mean viewing and up directions.
	ViewFrame vf;
	cv::Point3d centroid(0, 0, 0);
	for (const cv::Point3d &p : points)
		centroid += p;
	if (!points.empty())
		centroid *= 1.0 / double(points.size());
	double extent = 1.0;
	for (const cv::Point3d &p : points)
		extent = std::max(extent, cv::norm(p - centroid));
	cv::Vec3d towards(0, 0, 0), up(0, 0, 0);
	for (const CameraModel &c : cameras) {
		const cv::Vec3d d = c.centre() - cv::Vec3d(centroid);
		towards += d * (1.0 / std::max(cv::norm(d), 1e-9));
		up += c.R.t() * cv::Vec3d(0, -1, 0); // image "up" is the camera's -y
	}
	if (cv::norm(towards) < 1e-9)
		towards = cv::Vec3d(0, 0, -1);
	towards *= 1.0 / cv::norm(towards);
	up -= towards * up.dot(towards);
	if (cv::norm(up) < 1e-9) {
		up = std::fabs(towards[1]) < 0.9 ? cv::Vec3d(0, 1, 0) : cv::Vec3d(1, 0, 0);
		up -= towards * up.dot(towards);
	}
	up *= 1.0 / cv::norm(up);
	vf.towards = towards;
	vf.up = up;
	vf.right = up.cross(towards);
	vf.extent = extent;
	vf.centre = centroid - cv::Point3d(towards) * extent;
	return vf;
}

Status fuse_models(const std::vector<PartialModel> &models, const std::vector<CameraModel> &cameras,
		   const FusionParams &params, Mesh *ret_mesh, FusionStats *ret_stats)
{
	FusionStats stats;
	// Global index of every model point, and the union of copies of the same grid point.
	std::vector<size_t> offset(models.size() + 1, 0);
	for (size_t m = 0; m < models.size(); ++m)
		offset[m + 1] = offset[m] + models[m].points.size();
	const size_t total = offset.back();
	stats.input_points = int(total);
	if (total < 3)
		return Status::error(-ENODATA, "fusion: only " + std::to_string(total) +
						       " triangulated points, too few for a mesh");
	UnionFind uf(total);
	std::unordered_map<int64_t, int> seen;
	std::vector<double> border(total);
	std::vector<int> model_of(total);
	for (size_t m = 0; m < models.size(); ++m) {
		const PartialModel &pm = models[m];
		const std::vector<double> bd = border_distances(pm);
		for (size_t i = 0; i < pm.points.size(); ++i) {
			const int g = int(offset[m] + i);
			border[size_t(g)] = bd[i];
			model_of[size_t(g)] = int(m);
			if (i >= pm.sources.size())
				continue;
			const PointMatch &s = pm.sources[i];
			for (const auto &[cam, sq] : {std::make_pair(pm.cam_a, s.square_a), std::make_pair(pm.cam_b, s.square_b)}) {
				if (cam < 0 || sq < 0)
					continue;
				auto [it, fresh] = seen.emplace(key(cam, sq, s.feature), g);
				if (!fresh)
					uf.unite(it->second, g);
			}
		}
	}
	std::unordered_map<int, int> group_index;
	std::vector<std::vector<int>> groups;
	for (size_t g = 0; g < total; ++g) {
		const int root = uf.find(int(g));
		auto [it, fresh] = group_index.emplace(root, int(groups.size()));
		if (fresh)
			groups.emplace_back();
		groups[size_t(it->second)].push_back(int(g));
	}
	std::vector<cv::Point3d> fused(groups.size());
	for (size_t k = 0; k < groups.size(); ++k) {
		std::vector<cv::Point3d> copies;
		std::vector<double> w;
		bool multi = false, centroid = false;
		for (int g : groups[k]) {
			const size_t m = size_t(model_of[size_t(g)]);
			const size_t i = size_t(g) - offset[m];
			centroid |= i < models[m].sources.size() && models[m].sources[i].feature == kCentroid;
			copies.push_back(models[m].points[size_t(g) - offset[m]]);
			w.push_back(border[size_t(g)]);
			multi |= model_of[size_t(g)] != model_of[size_t(groups[k][0])];
		}
		fused[k] = blend(copies, w, params.border_floor_mm);
		stats.merged += multi;
		stats.squares += centroid;
	}

	// One sheet over a view sphere around the head.
	const ViewFrame vf = view_frame(fused, cameras);
	std::vector<cv::Vec3d> centres;
	for (const CameraModel &c : cameras)
		centres.push_back(c.centre());
	const cv::Point3d centre = vf.centre;
	const cv::Vec3d right = vf.right, up = vf.up, towards = vf.towards;
	const double extent = vf.extent;
	std::vector<cv::Point2d> sites(fused.size());
	for (size_t k = 0; k < fused.size(); ++k) {
		const cv::Vec3d d = cv::Vec3d(fused[k] - centre);
		const double x = d.dot(right), y = d.dot(up), z = d.dot(towards);
		sites[k] = cv::Point2d(std::atan2(x, z), std::atan2(y, std::hypot(x, z))) * extent;
	}
	const std::vector<cv::Vec3i> tris =
		filter_triangles(fused, delaunay_2d(sites), centres, centre, params.meshing, &stats.meshing);

	// Keep only vertices some triangle uses.
	std::vector<int> remap(fused.size(), -1);
	Mesh mesh;
	for (const cv::Vec3i &t : tris) {
		cv::Vec3i out;
		for (int k = 0; k < 3; ++k) {
			int &r = remap[size_t(t[k])];
			if (r < 0) {
				r = int(mesh.positions.size());
				mesh.positions.emplace_back(fused[size_t(t[k])]);
			}
			out[k] = r;
		}
		mesh.triangles.push_back(out);
	}
	if (mesh.triangles.empty())
		return Status::error(-ENODATA, "fusion: no triangle survived meshing of " +
						       std::to_string(fused.size()) + " points");
	mesh.normals = vertex_normals(mesh.positions, mesh.triangles);
	stats.vertices = int(mesh.positions.size());
	stats.triangles = int(mesh.triangles.size());
	*ret_mesh = std::move(mesh);
	if (ret_stats)
		*ret_stats = stats;
	return {};
}

} // namespace facescan::recon
