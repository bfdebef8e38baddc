// Stage 9 (dense): fusion of the dense clouds over the view sphere. See surface.hpp.
#include "recon/surface.hpp"

#include "recon/fusion.hpp"

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace facescan::recon {

namespace {

struct Sample {
	float u, v, r, w; // grid coordinates (cells), radius mm, weight
	int cloud;
	cv::Point3f p;
};

} // namespace

Status fuse_dense(const std::vector<DenseCloud> &clouds, const std::vector<cv::Point3f> &code_points,
		  const std::vector<CameraModel> &cameras, const SurfaceParams &params, Mesh *ret_mesh,
		  SurfaceStats *ret_stats)
{
	SurfaceStats stats;
	// A cell's vertex is its samples' weighted mean: with no weight floor an empty cell would
	// divide 0 by 0 and its NaN would reach the grid's indices.
	if (!(params.spacing_mm > 0) || !(params.agree_mm > 0) || params.max_cells < 16 || !(params.min_weight > 0))
		return Status::error(-EINVAL, "surface: spacing, agreement, grid size and weight floor must be positive");
	std::vector<cv::Point3d> some;
	size_t total = 0;
	for (const DenseCloud &c : clouds)
		total += c.points.size();
	stats.input_points = int(total);
	if (total < 3)
		return Status::error(-ENODATA, "surface: no dense points to fuse");
	const size_t stride = std::max<size_t>(1, total / 20000);
	size_t k = 0;
	for (const DenseCloud &c : clouds)
		for (const cv::Point3f &p : c.points)
			if (k++ % stride == 0)
				some.emplace_back(p);
	const ViewFrame vf = view_frame(some, cameras);
	// A direction from the sphere's centre (d, any length) as the grid's two angles, radians.
	auto angles_of = [&](const cv::Vec3d &d) {
		const double x = d.dot(vf.right), y = d.dot(vf.up), z = d.dot(vf.towards);
		return cv::Point2d(std::atan2(x, z), std::atan2(y, std::hypot(x, z)));
	};

	// Directions → angles; the grid step in angle is the spacing at the median radius.
	std::vector<Sample> samples;
	samples.reserve(total);
	std::vector<double> radii;
	float umin = 1e9f, umax = -1e9f, vmin = 1e9f, vmax = -1e9f;
	for (size_t ci = 0; ci < clouds.size(); ++ci) {
		const DenseCloud &c = clouds[ci];
		for (size_t i = 0; i < c.points.size(); ++i) {
			const cv::Vec3d d = cv::Vec3d(cv::Point3d(c.points[i]) - vf.centre);
			const double r = cv::norm(d);
			if (!(r > 1e-6) || !std::isfinite(r))
				continue;
			const cv::Point2d a = angles_of(d);
			const float u = float(a.x), v = float(a.y);
			const double border = std::min<double>(c.border_mm[i], params.border_cap_mm);
			const float w = float((border + params.border_floor_mm) * std::max(0.05f, c.confidence[i]));
			samples.push_back({u, v, float(r), w, int(ci), c.points[i]});
			umin = std::min(umin, u);
			umax = std::max(umax, u);
			vmin = std::min(vmin, v);
			vmax = std::max(vmax, v);
			if (samples.size() % 16 == 0)
				radii.push_back(r);
		}
	}
	if (samples.size() < 3 || radii.empty())
		return Status::error(-ENODATA, "surface: no dense points in front of the view sphere's centre");
	std::nth_element(radii.begin(), radii.begin() + long(radii.size() / 2), radii.end());
	const double r_med = radii[radii.size() / 2];
	double step = params.spacing_mm / r_med; // radians per cell
	auto cells_for = [&](double st) {
		return (long(double(umax - umin) / st) + 3) * (long(double(vmax - vmin) / st) + 3);
	};
	while (cells_for(step) > params.max_cells)
		step *= 1.25;
	stats.spacing_mm = step * r_med;
	const int W = int(double(umax - umin) / step) + 3, H = int(double(vmax - vmin) / step) + 3;
	// Angles → grid coordinates (cells; a one-cell margin on every side).
	auto to_cells = [&](const cv::Point2d &a) {
		return cv::Point2f(float((a.x - double(umin)) / step) + 1, float((a.y - double(vmin)) / step) + 1);
	};
	for (Sample &s : samples) {
		const cv::Point2f g = to_cells(cv::Point2d(s.u, s.v));
		s.u = g.x;
		s.v = g.y;
	}

	// Pass 1: each cell's strongest sample (bilinear splat weight times the sample's own).
	const size_t n = size_t(W) * size_t(H);
	std::vector<float> best_r(n, 0.f), best_w(n, 0.f);
	auto splat = [&](const Sample &s, auto &&fn) {
		const int x0 = int(std::floor(s.u)), y0 = int(std::floor(s.v));
		const float fx = s.u - float(x0), fy = s.v - float(y0);
		const float wx[2] = {1 - fx, fx}, wy[2] = {1 - fy, fy};
		for (int dy = 0; dy < 2; ++dy)
			for (int dx = 0; dx < 2; ++dx) {
				const int x = x0 + dx, y = y0 + dy;
				if (x < 0 || y < 0 || x >= W || y >= H)
					continue;
				fn(size_t(y) * size_t(W) + size_t(x), wx[dx] * wy[dy] * s.w);
			}
	};
	for (const Sample &s : samples)
		splat(s, [&](size_t c, float w) {
			if (w > best_w[c]) {
				best_w[c] = w;
				best_r[c] = s.r;
			}
		});
	// Pass 2: the weighted mean of the samples that agree with the strongest one.
	// A cell's vertex is the weighted mean of its samples' positions, not its centre's direction at
	// their mean radius: on a surface slanted against the sphere the two differ by the slope times
	// the samples' offset from the centre.
	std::vector<cv::Point3f> sum_wp(n, cv::Point3f(0, 0, 0));
	std::vector<float> sum_w(n, 0.f);
	std::vector<unsigned char> from(n, 0); // bit per cloud (first 8)
	auto two_or_more = [&](size_t c) { return (from[c] & (from[c] - 1)) != 0; };
	const float agree = float(params.agree_mm);
	for (const Sample &s : samples)
		splat(s, [&](size_t c, float w) {
			if (std::fabs(s.r - best_r[c]) > agree)
				return;
			sum_wp[c] += w * s.p;
			sum_w[c] += w;
			from[c] |= (unsigned char)(1u << (s.cloud & 7));
		});
	samples.clear();
	samples.shrink_to_fit();
	std::vector<float> radius(n, 0.f);
	std::vector<cv::Point3f> pos(n, cv::Point3f(0, 0, 0));
	const cv::Point3f centre(vf.centre);
	const float min_w = float(params.min_weight);
	for (size_t c = 0; c < n; ++c)
		if (sum_w[c] >= min_w) {
			pos[c] = sum_wp[c] * (1.f / sum_w[c]);
			radius[c] = float(cv::norm(pos[c] - centre));
			stats.cells++;
			stats.merged += two_or_more(c);
		}
	// Smoothing: each vertex moves to the weighted mean of its agreeing 3x3 neighbourhood.
	for (int pass = 0; pass < params.smooth_passes; ++pass) {
		std::vector<cv::Point3f> next = pos;
		for (int y = 1; y + 1 < H; ++y)
			for (int x = 1; x + 1 < W; ++x) {
				const size_t c = size_t(y) * size_t(W) + size_t(x);
				if (radius[c] <= 0)
					continue;
				double sw = 0;
				cv::Point3d swp(0, 0, 0);
				for (int dy = -1; dy <= 1; ++dy)
					for (int dx = -1; dx <= 1; ++dx) {
						const size_t q = size_t(y + dy) * size_t(W) + size_t(x + dx);
						if (radius[q] <= 0 || std::fabs(radius[q] - radius[c]) > agree)
							continue;
						const double w = sum_w[q] * (dx == 0 && dy == 0 ? 2.0 : 1.0);
						sw += w;
						swp += w * cv::Point3d(pos[q]);
					}
				next[c] = cv::Point3f(swp * (1.0 / sw));
			}
		pos.swap(next);
		for (size_t c = 0; c < n; ++c)
			if (radius[c] > 0)
				radius[c] = float(cv::norm(pos[c] - centre));
	}

	// Outliers: a radius farther than `max_median_dev_mm` from the median of its neighbourhood is
	// a mismatch (a dark nostril, an eye corner) the pair's own checks let through.
	if (params.median_radius > 0) {
		const int R = params.median_radius;
		std::vector<float> next = radius;
		// Rows are independent (each reads `radius`, writes its own cells of `next`): a median per
		// cell is the stage's largest cost, so they are spread over the cores.
		std::vector<int> row_outliers(size_t(H), 0);
		cv::parallel_for_(cv::Range(0, H), [&](const cv::Range &rows) {
			std::vector<float> win;
			for (int y = rows.start; y < rows.end; ++y)
				for (int x = 0; x < W; ++x) {
					const size_t c = size_t(y) * size_t(W) + size_t(x);
					if (radius[c] <= 0)
						continue;
					win.clear();
					size_t near = 0; // neighbours (and itself) within the limit of its radius
					const float r = radius[c], dev = float(params.max_median_dev_mm);
					for (int dy = -R; dy <= R; ++dy)
						for (int dx = -R; dx <= R; ++dx) {
							const int xx = x + dx, yy = y + dy;
							if (xx < 0 || yy < 0 || xx >= W || yy >= H)
								continue;
							const float q = radius[size_t(yy) * size_t(W) + size_t(xx)];
							if (q > 0) {
								win.push_back(q);
								near += std::fabs(q - r) <= dev;
							}
						}
					// When more than half the window lies within the limit of r, so does its
					// median (win[size / 2] sorted): no selection needed — most cells.
					if (near > win.size() / 2)
						continue;
					std::nth_element(win.begin(), win.begin() + long(win.size() / 2), win.end());
					if (std::fabs(win[win.size() / 2] - r) > dev) {
						next[c] = 0;
						row_outliers[size_t(y)]++;
					}
				}
		});
		for (int k : row_outliers)
			stats.outliers += k;
		radius.swap(next);
	}

	// Plane fit: each radius becomes the value, at its own direction, of the plane r(u, v) fitted
	// (weighted least squares) to the agreeing radii of its window. A slanted surface and a
	// one-sided window at the outline or at a hole keep their place (to ~0.01 mm: a plane's radius
	// is not quite linear in the angles), which the 3-D mean above does not (more passes of it
	// pull the outline in); another sheet beyond `agree_mm` takes no part. The vertex moves along
	// its ray from the sphere's centre, so the outline stays where the pairs put it.
	const int fit_cells =
		params.plane_fit_mm > 0 ? std::max(1, int(std::lround(params.plane_fit_mm / stats.spacing_mm))) : 0;
	if (fit_cells > 0) {
		// Each vertex's direction in grid units, from its position (not its cell's centre).
		std::vector<cv::Point2f> uv(n);
		for (size_t c = 0; c < n; ++c)
			if (radius[c] > 0)
				uv[c] = to_cells(angles_of(cv::Vec3d(cv::Point3d(pos[c]) - vf.centre)));
		const int R = fit_cells;
		std::vector<float> fitted = radius;
		// Rows are independent (each reads `radius`, writes its own cells of `fitted`).
		cv::parallel_for_(cv::Range(0, H), [&](const cv::Range &rows) {
			for (int y = rows.start; y < rows.end; ++y)
				for (int x = 0; x < W; ++x) {
					const size_t c = size_t(y) * size_t(W) + size_t(x);
					if (radius[c] <= 0)
						continue;
					// Normal equations of r - r_c = a + b du + c dv (the 6 sums of the symmetric
					// matrix and the 3 of the right-hand side), relative to the cell.
					const float rc = radius[c], uc = uv[c].x, vc = uv[c].y;
					// Single precision is enough (offsets of a few cells, radii within agree_mm of
					// each other); a cell that does not agree adds zeros rather than a branch.
					float s1 = 0, su = 0, sv = 0, suu = 0, suv = 0, svv = 0, sr = 0, sur = 0, svr = 0;
					int used = 0;
					for (int yy = std::max(0, y - R); yy <= std::min(H - 1, y + R); ++yy) {
						const size_t row = size_t(yy) * size_t(W);
						for (int xx = std::max(0, x - R); xx <= std::min(W - 1, x + R); ++xx) {
							const size_t q = row + size_t(xx);
							const float dr = radius[q] - rc;
							const bool agrees = radius[q] > 0 && std::fabs(dr) <= agree;
							const float w = agrees ? sum_w[q] : 0.f, du = uv[q].x - uc, dv = uv[q].y - vc;
							const float wu = w * du, wv = w * dv;
							s1 += w;
							su += wu;
							sv += wv;
							suu += wu * du;
							suv += wu * dv;
							svv += wv * dv;
							sr += w * dr;
							sur += wu * dr;
							svr += wv * dr;
							used += agrees;
						}
					}
					// Only the plane's value at the cell is wanted: Cramer's rule for a. A window
					// whose cells lie on one line (a thin strip) has no plane: left as it is.
					const double a00 = s1, a01 = su, a02 = sv, a11 = suu, a12 = suv, a22 = svv;
					const double det = a00 * (a11 * a22 - a12 * a12) - a01 * (a01 * a22 - a12 * a02) +
							   a02 * (a01 * a12 - a11 * a02);
					if (used < 6 || !(det > 1e-6 * a00 * a11 * a22))
						continue;
					const double det_a = double(sr) * (a11 * a22 - a12 * a12) -
							     a01 * (double(sur) * a22 - a12 * double(svr)) +
							     a02 * (double(sur) * a12 - a11 * double(svr));
					fitted[c] = rc + float(det_a / det);
				}
		});
		for (size_t c = 0; c < n; ++c)
			if (radius[c] > 0 && fitted[c] > 0) {
				pos[c] = centre + (pos[c] - centre) * (fitted[c] / radius[c]);
				radius[c] = fitted[c];
			}
	}

	// The outline trimmed; a pinhole is not outline (eroding around it would only widen it).
	if (params.trim_border_cells > 0) {
		cv::Mat present(H, W, CV_8U, cv::Scalar(0));
		for (size_t c = 0; c < n; ++c)
			present.data[c] = radius[c] > 0 ? 255 : 0;
		const cv::Mat inner =
			erode_outline(present, params.pinhole_cells, params.trim_border_cells, cv::MORPH_CROSS);
		for (size_t c = 0; c < n; ++c)
			if (radius[c] > 0 && !inner.data[c]) {
				radius[c] = 0;
				stats.trimmed++;
			}
	}

	// Vertices: one per cell with a radius.
	Mesh mesh;
	std::vector<int> vid(n, -1);
	for (int y = 0; y < H; ++y)
		for (int x = 0; x < W; ++x) {
			const size_t c = size_t(y) * size_t(W) + size_t(x);
			if (radius[c] <= 0)
				continue;
			vid[c] = int(mesh.positions.size());
			mesh.positions.push_back(pos[c]);
		}
	// Triangles: two per grid square (one when a corner is missing), none across a jump.
	const double max_edge = params.max_edge_steps * stats.spacing_mm;
	const double max_edge2 = max_edge * max_edge;
	auto edge_ok = [&](int i, int j) {
		const cv::Point3f d = mesh.positions[size_t(i)] - mesh.positions[size_t(j)];
		return double(d.dot(d)) <= max_edge2;
	};
	auto add = [&](int i, int j, int l) {
		if (i < 0 || j < 0 || l < 0 || !edge_ok(i, j) || !edge_ok(j, l) || !edge_ok(l, i))
			return;
		// Outward: away from the sphere's centre. Grid (x right, y up) seen from outside is
		// counter-clockwise for (i, j, l) = (x, y), (x+1, y), (x, y+1); check rather than trust.
		const cv::Point3f a = mesh.positions[size_t(i)], b = mesh.positions[size_t(j)],
				  c = mesh.positions[size_t(l)];
		const cv::Point3f nrm = (b - a).cross(c - a);
		const cv::Point3f out = (a + b + c) * (1.f / 3) - cv::Point3f(vf.centre);
		if (nrm.dot(out) >= 0)
			mesh.triangles.emplace_back(i, j, l);
		else
			mesh.triangles.emplace_back(i, l, j);
	};
	for (int y = 0; y + 1 < H; ++y)
		for (int x = 0; x + 1 < W; ++x) {
			const size_t c = size_t(y) * size_t(W) + size_t(x);
			const int v00 = vid[c], v10 = vid[c + 1], v01 = vid[c + size_t(W)], v11 = vid[c + size_t(W) + 1];
			const int present = (v00 >= 0) + (v10 >= 0) + (v01 >= 0) + (v11 >= 0);
			if (present == 4) {
				add(v00, v10, v11);
				add(v00, v11, v01);
			} else if (present == 3) {
				if (v00 < 0)
					add(v10, v11, v01);
				else if (v10 < 0)
					add(v00, v11, v01);
				else if (v01 < 0)
					add(v00, v10, v11);
				else
					add(v00, v10, v01);
			}
		}
	// Pieces: a sheet split off the face by a gap (a rim of the crown seen at grazing angles, a
	// speck of hair) is more often wrong than right; only pieces of at least `min_piece_fraction`
	// of the largest one stay — and smaller ones two pairs agree on (`piece_two_pair_fraction` of
	// their vertices averaged from two clouds): one pair's mismatch is not repeated by another
	// pair, with its own cameras, at the same place.
	{
		std::vector<int> parent(mesh.positions.size());
		for (size_t i = 0; i < parent.size(); ++i)
			parent[i] = int(i);
		auto find = [&](int i) {
			while (parent[size_t(i)] != i) {
				parent[size_t(i)] = parent[size_t(parent[size_t(i)])];
				i = parent[size_t(i)];
			}
			return i;
		};
		for (const cv::Vec3i &t : mesh.triangles)
			for (int q = 1; q < 3; ++q) {
				const int a = find(t[0]), b = find(t[q]);
				if (a != b)
					parent[size_t(a)] = b;
			}
		std::vector<int> size(parent.size(), 0), vertices(parent.size(), 0), merged(parent.size(), 0);
		for (const cv::Vec3i &t : mesh.triangles)
			size[size_t(find(t[0]))]++;
		for (size_t c = 0; c < n; ++c)
			if (vid[c] >= 0) {
				const size_t r = size_t(find(vid[c]));
				vertices[r]++;
				merged[r] += two_or_more(c);
			}
		const int largest = size.empty() ? 0 : *std::max_element(size.begin(), size.end());
		const double min_size = params.min_piece_fraction * largest;
		auto two_pairs = [&](size_t r) {
			return params.piece_two_pair_fraction > 0 && merged[r] >= params.piece_two_pair_fraction * vertices[r];
		};
		// What the size and two-pair rules drop.
		auto dropped = [&](size_t r) { return size[r] < min_size && !two_pairs(r); };
		// The code's points vouch for small pieces: a code point with a vertex of a piece within
		// `piece_code_mm` counts for that piece, and vouches for the piece's vertices whose cells lie
		// within `piece_code_reach_mm` of its own (a piece can be right near the code and wrong
		// beyond). The candidates are the vertices of the cells around the code point's direction.
		std::vector<int> code_near(parent.size(), 0);
		std::vector<char> vouched(mesh.positions.size(), 0); // per vertex
		if (params.piece_code_points > 0 && params.piece_code_mm > 0) {
			const int near = int(std::ceil(params.piece_code_mm / stats.spacing_mm)) + 1;
			const int reach = int(std::ceil(params.piece_code_reach_mm / stats.spacing_mm));
			const float within2 = float(params.piece_code_mm * params.piece_code_mm);
			std::vector<int> counted; // the pieces this code point counts for
			for (const cv::Point3f &q : code_points) {
				const cv::Vec3d d = cv::Vec3d(cv::Point3d(q) - vf.centre);
				if (!(cv::norm(d) > 1e-6))
					continue;
				const cv::Point2f g = to_cells(angles_of(d));
				if (!(g.x >= 0 && g.y >= 0 && g.x < float(W) && g.y < float(H)))
					continue;
				const int gx = int(g.x), gy = int(g.y);
				counted.clear();
				for (int y = std::max(0, gy - near); y <= std::min(H - 1, gy + near); ++y)
					for (int x = std::max(0, gx - near); x <= std::min(W - 1, gx + near); ++x) {
						const int v = vid[size_t(y) * size_t(W) + size_t(x)];
						if (v < 0)
							continue;
						const cv::Point3f e = mesh.positions[size_t(v)] - q;
						const int r = find(v);
						// Only the pieces the rules above drop need the code's word.
						if (e.dot(e) <= within2 && dropped(size_t(r)) &&
						    std::find(counted.begin(), counted.end(), r) == counted.end())
							counted.push_back(r);
					}
				for (const int r : counted) {
					code_near[size_t(r)]++;
					for (int y = std::max(0, gy - reach); y <= std::min(H - 1, gy + reach); ++y)
						for (int x = std::max(0, gx - reach); x <= std::min(W - 1, gx + reach); ++x) {
							const int v = vid[size_t(y) * size_t(W) + size_t(x)];
							if ((x - gx) * (x - gx) + (y - gy) * (y - gy) <= reach * reach && v >= 0 &&
							    find(v) == r)
								vouched[size_t(v)] = 1;
						}
				}
			}
		}
		std::vector<cv::Vec3i> kept;
		kept.reserve(mesh.triangles.size());
		for (const cv::Vec3i &t : mesh.triangles) {
			const size_t r = size_t(find(t[0]));
			if (!dropped(r)) {
				kept.push_back(t);
				stats.piece_triangles_two_pairs += size[r] < min_size;
			} else if (params.piece_code_points > 0 && code_near[r] >= params.piece_code_points &&
				   vouched[size_t(t[0])] && vouched[size_t(t[1])] && vouched[size_t(t[2])]) {
				kept.push_back(t);
				stats.piece_triangles_code++;
			} else {
				stats.piece_triangles_dropped++;
			}
		}
		mesh.triangles.swap(kept);
	}

	// Keep only vertices some triangle uses.
	std::vector<int> remap(mesh.positions.size(), -1);
	Mesh out;
	for (cv::Vec3i &t : mesh.triangles)
		for (int q = 0; q < 3; ++q) {
			int &r = remap[size_t(t[q])];
			if (r < 0) {
				r = int(out.positions.size());
				out.positions.push_back(mesh.positions[size_t(t[q])]);
			}
			t[q] = r;
		}
	out.triangles = std::move(mesh.triangles);
	if (out.triangles.empty())
		return Status::error(-ENODATA, "surface: no triangle survived over " + std::to_string(stats.cells) +
						       " cells");
	out.normals = vertex_normals(out.positions, out.triangles);
	stats.vertices = int(out.positions.size());
	stats.triangles = int(out.triangles.size());
	*ret_mesh = std::move(out);
	if (ret_stats)
		*ret_stats = stats;
	return {};
}

} // namespace facescan::recon
