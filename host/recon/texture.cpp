// Stage 10: texture. See texture.hpp.
#include "recon/texture.hpp"
#include "recon/raster.hpp"
#include "recon/triangulate.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace facescan::recon {

namespace {

cv::Vec3b sample(const cv::Mat &img, const cv::Point2d &p)
{
	const int x = std::clamp(int(std::lround(p.x)), 0, img.cols - 1);
	const int y = std::clamp(int(std::lround(p.y)), 0, img.rows - 1);
	return img.at<cv::Vec3b>(y, x);
}

} // namespace

Status texture_mesh(const std::vector<cv::Mat> &textures, const std::vector<cv::Mat> &frames,
		    const std::vector<CameraModel> &cameras, const TextureParams &params, Mesh *mesh,
		    TextureStats *ret_stats)
{
	TextureStats stats;
	const bool have_textures = !textures.empty();
	const std::vector<cv::Mat> &images = have_textures ? textures : frames;
	if (images.size() != cameras.size())
		return Status::error(-EINVAL, "texture: " + std::to_string(images.size()) + " images for " +
						      std::to_string(cameras.size()) + " cameras");
	for (size_t c = 0; c < images.size(); ++c)
		if (images[c].empty() || images[c].type() != CV_8UC3)
			return Status::error(-EINVAL, "texture: image of camera " + std::to_string(c) +
							      " is empty or not 8-bit BGR");
	const size_t nv = mesh->positions.size(), nt = mesh->triangles.size(), nc = cameras.size();
	stats.vertices_before = int(nv);
	std::vector<cv::Point3d> pts(mesh->positions.begin(), mesh->positions.end());

	// Per camera: projections and visibility of every vertex.
	std::vector<std::vector<cv::Point2d>> px(nc);
	std::vector<std::vector<char>> vis(nc);
	cv::parallel_for_(cv::Range(0, int(nc)), [&](const cv::Range &r) {
		for (int c = r.start; c < r.end; ++c) {
			// Projected once: the z-buffer and the visibility test need the same pixels.
			px[size_t(c)] = project_points(cameras[size_t(c)], pts);
			const cv::Mat depth = render_depth(cameras[size_t(c)], mesh->positions, mesh->triangles,
							   params.depth_scale, &px[size_t(c)]);
			vis[size_t(c)] = visible_in(cameras[size_t(c)], depth, params.depth_scale, pts,
						    params.occlusion_tolerance_mm, &px[size_t(c)]);
		}
	});

	// Best camera per triangle.
	std::vector<int> best(nt, 0);
	for (size_t t = 0; t < nt; ++t) {
		const cv::Vec3i &tri = mesh->triangles[t];
		const cv::Point3d a = pts[size_t(tri[0])], b = pts[size_t(tri[1])], c3 = pts[size_t(tri[2])];
		cv::Point3d n = (b - a).cross(c3 - a);
		n *= 1.0 / std::max(cv::norm(n), 1e-12);
		const cv::Point3d g = (a + b + c3) * (1.0 / 3.0);
		double best_score = -2, fallback_score = -2;
		int best_cam = -1, fallback = 0;
		for (size_t c = 0; c < nc; ++c) {
			const cv::Point3d v = cv::Point3d(cameras[c].centre()) - g;
			const double cosv = n.dot(v) / cv::norm(v);
			if (cosv > fallback_score) {
				fallback_score = cosv;
				fallback = int(c);
			}
			const bool seen = vis[c][size_t(tri[0])] && vis[c][size_t(tri[1])] && vis[c][size_t(tri[2])];
			if (seen && cosv >= params.min_cos && cosv > best_score) {
				best_score = cosv;
				best_cam = int(c);
			}
		}
		if (best_cam < 0) {
			stats.untextured++;
			best_cam = fallback;
		}
		best[t] = best_cam;
	}

	if (!have_textures) {
		// Fallback: per-vertex colour from the camera that sees the vertex most frontally.
		mesh->colours.assign(nv, cv::Vec3b(0, 0, 0));
		std::vector<double> score(nv, -2);
		for (size_t t = 0; t < nt; ++t)
			for (int k = 0; k < 3; ++k) {
				const size_t v = size_t(mesh->triangles[t][k]);
				const int c = best[t];
				const cv::Vec3d view = cameras[size_t(c)].centre() - cv::Vec3d(pts[v]);
				const cv::Point3f &nrm = mesh->normals.size() == nv ? mesh->normals[v] : cv::Point3f(0, 0, 0);
				const double s = cv::Vec3d(nrm.x, nrm.y, nrm.z).dot(view) / cv::norm(view);
				if (s > score[v]) {
					score[v] = s;
					mesh->colours[v] = sample(images[size_t(c)], px[size_t(c)][v]);
				}
			}
		mesh->uvs.clear();
		mesh->texture.release();
		stats.vertex_colours = true;
		stats.vertices_after = int(nv);
		if (ret_stats)
			*ret_stats = stats;
		return {};
	}

	// Charts: each used camera's bounding box of its triangles' projections.
	std::vector<cv::Rect> crop(nc);
	std::vector<char> used(nc, 0);
	std::vector<cv::Rect2d> box(nc, cv::Rect2d());
	std::vector<double> x0(nc, 1e30), y0(nc, 1e30), x1(nc, -1e30), y1(nc, -1e30);
	for (size_t t = 0; t < nt; ++t) {
		const size_t c = size_t(best[t]);
		used[c] = 1;
		for (int k = 0; k < 3; ++k) {
			const cv::Point2d &p = px[c][size_t(mesh->triangles[t][k])];
			x0[c] = std::min(x0[c], p.x);
			y0[c] = std::min(y0[c], p.y);
			x1[c] = std::max(x1[c], p.x);
			y1[c] = std::max(y1[c], p.y);
		}
	}
	int atlas_w = 0, atlas_h = 0;
	std::vector<int> offset_x(nc, 0);
	for (size_t c = 0; c < nc; ++c) {
		if (!used[c])
			continue;
		const cv::Rect img(0, 0, images[c].cols, images[c].rows);
		const int pad = params.padding_px;
		cv::Rect r(int(std::floor(x0[c])) - pad, int(std::floor(y0[c])) - pad, 0, 0);
		r.width = int(std::ceil(x1[c])) + pad + 1 - r.x;
		r.height = int(std::ceil(y1[c])) + pad + 1 - r.y;
		crop[c] = r & img;
		if (crop[c].empty())
			crop[c] = cv::Rect(0, 0, 1, 1);
		offset_x[c] = atlas_w;
		atlas_w += crop[c].width;
		atlas_h = std::max(atlas_h, crop[c].height);
		stats.charts++;
	}
	const double shrink = atlas_w > params.max_atlas_width ? double(params.max_atlas_width) / atlas_w : 1.0;
	cv::Mat atlas(atlas_h, atlas_w, CV_8UC3, cv::Scalar(0, 0, 0));
	for (size_t c = 0; c < nc; ++c)
		if (used[c])
			images[c](crop[c]).copyTo(atlas(cv::Rect(offset_x[c], 0, crop[c].width, crop[c].height)));
	if (shrink < 1.0)
		cv::resize(atlas, atlas, cv::Size(), shrink, shrink, cv::INTER_AREA);

	// Split vertices per chart: (vertex, camera) → output vertex with that chart's UV.
	Mesh out;
	std::vector<int> split(nv * nc, -1); // (vertex, camera) → output vertex
	const double aw = atlas_w, ah = atlas_h;
	for (size_t t = 0; t < nt; ++t) {
		const int c = best[t];
		cv::Vec3i tri;
		for (int k = 0; k < 3; ++k) {
			const int v = mesh->triangles[t][k];
			int &id = split[size_t(v) * nc + size_t(c)];
			if (id < 0) {
				id = int(out.positions.size());
				out.positions.push_back(mesh->positions[size_t(v)]);
				if (mesh->normals.size() == nv)
					out.normals.push_back(mesh->normals[size_t(v)]);
				const cv::Point2d p = px[size_t(c)][size_t(v)];
				// Continuous image coordinate of pixel centre i is i + 0.5; v runs downwards.
				const double u = (p.x + 0.5 - crop[size_t(c)].x + offset_x[size_t(c)]) / aw;
				const double w = (p.y + 0.5 - crop[size_t(c)].y) / ah;
				out.uvs.emplace_back(float(std::clamp(u, 0.0, 1.0)), float(std::clamp(w, 0.0, 1.0)));
			}
			tri[k] = id;
		}
		out.triangles.push_back(tri);
	}
	out.texture = atlas;
	stats.vertices_after = int(out.positions.size());
	stats.atlas = atlas.size();
	*mesh = std::move(out);
	if (ret_stats)
		*ret_stats = stats;
	return {};
}

} // namespace facescan::recon
