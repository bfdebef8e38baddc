// Rendering the booth: rays from every camera pixel (through the lens distortion) → Embree hit
// → light from each projector (shadow ray, slide look-up with depth-dependent defocus,
// Lambert + inverse-square fall-off + a little sheen), ambient and diffuse light → camera
// defocus → sensor (crosstalk, Bayer mosaic, shot + read noise, ADC, demosaic, gamma, 8 bit).
// Values are "sensor linear": 1.0 is a full well at exposure 1.
#include "sim/internal.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

namespace facescan::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRefDistance = 500; // mm: where SimProjector::power is defined

// A slide as linear light, pre-blurred at a ladder of sigmas (slide pixels) for the
// depth-dependent projector defocus.
struct SlideStack {
	std::vector<double> sigmas;
	std::vector<cv::Mat> levels; // CV_32FC3, RGB order, linear

	static SlideStack make(const cv::Mat &bgr, cv::Size size, double gamma,
			       const std::vector<cv::Point2d> &mask)
	{
		SlideStack s;
		cv::Mat img = bgr;
		if (img.size() != size)
			cv::resize(bgr, img, size, 0, 0, cv::INTER_AREA);
		cv::Mat rgb, lin;
		cv::cvtColor(img, rgb, cv::COLOR_BGR2RGB);
		rgb.convertTo(lin, CV_32FC3, 1.0 / 255);
		cv::pow(lin, gamma, lin);
		if (!mask.empty()) {
			// A physical mask in the slide plane: black outside the polygon (sub-pixel edge
			// positions, 8 fractional bits), blurred with the slide by the projector's defocus.
			const int shift = 8;
			std::vector<cv::Point> poly;
			for (const cv::Point2d &q : mask)
				poly.emplace_back(int(std::lround(q.x * (1 << shift))), int(std::lround(q.y * (1 << shift))));
			cv::Mat m = cv::Mat::zeros(size, CV_8U);
			cv::fillPoly(m, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255), cv::LINE_8, shift);
			cv::Mat m3;
			cv::cvtColor(m, m3, cv::COLOR_GRAY2RGB);
			m3.convertTo(m3, CV_32FC3, 1.0 / 255);
			lin = lin.mul(m3);
		}
		s.sigmas = {0.0, 0.5, 1.0, 2.0, 4.0, 8.0};
		for (double sg : s.sigmas) {
			cv::Mat b;
			if (sg == 0)
				b = lin;
			else
				cv::GaussianBlur(lin, b, cv::Size(), sg, sg, cv::BORDER_CONSTANT);
			s.levels.push_back(b);
		}
		return s;
	}

	static cv::Vec3f bilinear(const cv::Mat &m, double x, double y)
	{
		int x0 = int(std::floor(x)), y0 = int(std::floor(y));
		float fx = float(x - x0), fy = float(y - y0);
		cv::Vec3f acc(0, 0, 0);
		for (int dy = 0; dy < 2; dy++)
			for (int dx = 0; dx < 2; dx++) {
				int xx = x0 + dx, yy = y0 + dy;
				if (xx < 0 || yy < 0 || xx >= m.cols || yy >= m.rows)
					continue;
				float w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
				acc += w * m.at<cv::Vec3f>(yy, xx);
			}
		return acc;
	}

	cv::Vec3f sample(double x, double y, double sigma) const
	{
		size_t i = 0;
		while (i + 1 < sigmas.size() && sigmas[i + 1] < sigma)
			i++;
		if (i + 1 >= sigmas.size())
			return bilinear(levels.back(), x, y);
		double t = std::clamp((sigma - sigmas[i]) / (sigmas[i + 1] - sigmas[i]), 0.0, 1.0);
		return float(1 - t) * bilinear(levels[i], x, y) + float(t) * bilinear(levels[i + 1], x, y);
	}
};

// A surface's texture as linear RGB floats.
cv::Mat linear_texture(const cv::Mat &bgr)
{
	if (bgr.empty())
		return cv::Mat();
	cv::Mat rgb, lin;
	if (bgr.channels() == 1)
		cv::cvtColor(bgr, rgb, cv::COLOR_GRAY2RGB);
	else
		cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
	rgb.convertTo(lin, CV_32FC3, bgr.depth() == CV_8U ? 1.0 / 255 : 1.0 / 65535);
	cv::pow(lin, 2.2, lin);
	return lin;
}

struct Light {
	cv::Vec3d dir;
	double intensity;
};

struct Shaded {
	cv::Vec3f pattern{0, 0, 0}, texture{0, 0, 0};
	float depth = 0;
	uint8_t surface = 0;
	int8_t projector = -1;
	cv::Vec2f slide_xy{-1, -1};
};

class Renderer {
public:
	Renderer(const Rig &rig, const std::vector<Surface> &surfaces, const Tracer &tracer,
		 const std::vector<const SlideStack *> &slides, const std::vector<cv::Mat> &textures,
		 const RenderOptions &options)
		: rig_(rig), surfaces_(surfaces), tracer_(tracer), slides_(slides), textures_(textures),
		  options_(options)
	{
		for (const DiffuseLight &l : rig.lighting.lights) {
			cv::Vec3d d = orbit_position(cv::Vec3d(0, 0, 0), l.azimuth_deg, l.elevation_deg, 1);
			lights_.push_back({d, l.intensity});
		}
	}

	Shaded shade(const cv::Vec3d &origin, const cv::Vec3d &dir, const CameraModel &cam) const
	{
		Shaded out;
		Hit hit = tracer_.intersect(origin, dir, 1.0);
		if (hit.surface < 0)
			return out;
		const Surface &s = surfaces_[size_t(hit.surface)];
		const Mesh &m = s.mesh;
		const cv::Vec3i &tri = m.triangles[size_t(hit.triangle)];
		float w0 = 1 - hit.u - hit.v, w1 = hit.u, w2 = hit.v;
		cv::Vec3d p = origin + double(hit.t) * dir;
		cv::Vec3d a = m.vertices[size_t(tri[0])], b = m.vertices[size_t(tri[1])],
			  c = m.vertices[size_t(tri[2])];
		cv::Vec3d ng = cv::normalize((b - a).cross(c - a));
		cv::Vec3d ns = ng;
		if (!m.normals.empty()) {
			cv::Vec3f n = w0 * m.normals[size_t(tri[0])] + w1 * m.normals[size_t(tri[1])] +
				      w2 * m.normals[size_t(tri[2])];
			double l = cv::norm(n);
			if (l > 1e-9)
				ns = cv::Vec3d(n) * (1.0 / l);
		}
		if (ng.dot(dir) > 0) { // seen from the back: shade the side the camera sees
			ng = -ng;
			ns = -ns;
		}
		cv::Vec3f albedo = s.albedo;
		if (!textures_[size_t(hit.surface)].empty() && !m.uv.empty()) {
			cv::Vec2f uv = w0 * m.uv[size_t(tri[0])] + w1 * m.uv[size_t(tri[1])] +
				       w2 * m.uv[size_t(tri[2])];
			const cv::Mat &t = textures_[size_t(hit.surface)];
			albedo = SlideStack::bilinear(t, double(uv[0]) * t.cols - 0.5, double(uv[1]) * t.rows - 0.5);
		} else if (!m.colors.empty()) {
			albedo = w0 * m.colors[size_t(tri[0])] + w1 * m.colors[size_t(tri[1])] +
				 w2 * m.colors[size_t(tri[2])];
		}
		cv::Vec3d x = cam.R * p + cam.T;
		out.depth = float(x[2]);
		out.surface = uint8_t(std::clamp(s.id, 0, 255));
		cv::Vec3d view = -dir;
		cv::Vec3d p_off = p + 0.02 * ng;

		cv::Vec3f proj(0, 0, 0), sheen(0, 0, 0);
		float best = 0;
		if (options_.pattern)
			for (size_t j = 0; j < rig_.projectors.size(); j++) {
				if (!options_.projectors_on.empty() && !options_.projectors_on[j])
					continue;
				const SimProjector &pr = rig_.projectors[j];
				cv::Vec3d xp = pr.R * p + pr.T;
				if (xp[2] <= 1)
					continue;
				cv::Vec3d uvw = pr.K * xp;
				double u = uvw[0] / uvw[2], v = uvw[1] / uvw[2];
				if (u < -20 || v < -20 || u > pr.size.width + 20 || v > pr.size.height + 20)
					continue;
				cv::Vec3d to = pr.centre() - p;
				double dist = cv::norm(to);
				cv::Vec3d l = to * (1.0 / dist);
				double cosi = ns.dot(l);
				if (cosi <= 0 || ng.dot(l) <= 0)
					continue;
				if (tracer_.occluded(p_off, l, 0.01, dist - 1))
					continue;
				double sigma = std::hypot(pr.blur_px, pr.defocus_px_per_100mm *
									   std::fabs(xp[2] - pr.focus_mm) / 100);
				cv::Vec3f e = slides_[j]->sample(u, v, sigma);
				double fall = pr.power * (kRefDistance / dist) * (kRefDistance / dist);
				proj += float(fall * cosi) * e;
				if (s.specular > 0) {
					cv::Vec3d hv = cv::normalize(l + view);
					double sp = std::pow(std::max(0.0, ns.dot(hv)), double(s.shininess));
					sheen += float(fall * s.specular * sp) * e;
				}
				float lum = float(cosi) * (e[0] + e[1] + e[2]);
				if (lum > best) {
					best = lum;
					out.projector = int8_t(j);
					out.slide_xy = cv::Vec2f(float(u), float(v));
				}
			}
		float amb_p = float(rig_.lighting.ambient_pattern);
		for (int k = 0; k < 3; k++)
			out.pattern[k] = albedo[k] * (proj[k] + amb_p) + sheen[k];
		if (options_.texture) {
			double diffuse = rig_.lighting.ambient_texture, spec = 0;
			for (const Light &l : lights_) {
				// Soft boxes: wrapped Lambert (light reaches a little past the terminator).
				double c = (ns.dot(l.dir) + 0.3) / 1.3;
				diffuse += l.intensity * std::max(0.0, c);
				if (s.specular > 0) {
					cv::Vec3d hv = cv::normalize(l.dir + view);
					spec += l.intensity * s.specular * 0.5 *
						std::pow(std::max(0.0, ns.dot(hv)), double(s.shininess) * 0.5);
				}
			}
			for (int k = 0; k < 3; k++)
				out.texture[k] = float(albedo[k] * diffuse + spec);
		}
		return out;
	}

private:
	const Rig &rig_;
	const std::vector<Surface> &surfaces_;
	const Tracer &tracer_;
	const std::vector<const SlideStack *> &slides_;
	const std::vector<cv::Mat> &textures_;
	const RenderOptions &options_;
	std::vector<Light> lights_;
};

// Camera defocus in two layers, so that a blurred background never bleeds over a sharp head:
// the near layer (premultiplied colour + coverage) is blurred per pixel by its circle of
// confusion (a blend of the two bracketing levels of a Gaussian ladder), the far layer (booth
// wall) by one sigma and renormalised; near is composited over far.
cv::Mat defocus(const cv::Mat &near_rgb, const cv::Mat &alpha, const cv::Mat &sigma_map,
		const cv::Mat &far_rgb, double far_sigma)
{
	cv::Mat near4, far4;
	cv::merge(std::vector<cv::Mat>{near_rgb, alpha}, near4);
	cv::Mat far_alpha = 1.0 - alpha;
	cv::merge(std::vector<cv::Mat>{far_rgb, far_alpha}, far4);
	if (far_sigma > 0.05)
		cv::GaussianBlur(far4, far4, cv::Size(), far_sigma, far_sigma, cv::BORDER_REFLECT);
	double lo = 0, hi = 0;
	cv::minMaxLoc(sigma_map, &lo, &hi);
	std::vector<double> sig = {0.0};
	for (double s = 0.35; s < hi * 1.6 + 0.35; s *= 1.6)
		sig.push_back(s);
	std::vector<cv::Mat> lv;
	for (double s : sig) {
		if (s == 0) {
			lv.push_back(near4);
			continue;
		}
		cv::Mat b;
		cv::GaussianBlur(near4, b, cv::Size(), s, s, cv::BORDER_REFLECT);
		lv.push_back(b);
	}
	cv::Mat out(near_rgb.size(), CV_32FC3);
	cv::parallel_for_(cv::Range(0, out.rows), [&](const cv::Range &r) {
		for (int y = r.start; y < r.end; y++)
			for (int x = 0; x < out.cols; x++) {
				double s = sigma_map.at<float>(y, x);
				size_t i = 0;
				while (i + 1 < sig.size() && sig[i + 1] < s)
					i++;
				cv::Vec4f n;
				if (i + 1 >= sig.size()) {
					n = lv.back().at<cv::Vec4f>(y, x);
				} else {
					float t = float(std::clamp((s - sig[i]) / (sig[i + 1] - sig[i]), 0.0, 1.0));
					n = (1 - t) * lv[i].at<cv::Vec4f>(y, x) + t * lv[i + 1].at<cv::Vec4f>(y, x);
				}
				const cv::Vec4f &f = far4.at<cv::Vec4f>(y, x);
				float fa = f[3] > 1e-4f ? 1.f / f[3] : 0.f;
				float keep = std::max(0.f, 1.f - n[3]);
				out.at<cv::Vec3f>(y, x) = cv::Vec3f(n[0] + keep * f[0] * fa, n[1] + keep * f[1] * fa,
								    n[2] + keep * f[2] * fa);
			}
	});
	return out;
}

// The sensor: linear RGB (sensor units) → 8-bit BGR as the camera delivers it.
cv::Mat sensor(const cv::Mat &rgb, const SensorModel &s, double exposure, bool noise, uint64_t key)
{
	const int maxv = (1 << s.adc_bits) - 1;
	const double fw = s.full_well_e;
	const double ns = noise ? s.noise_scale : 0;
	const cv::Matx33f ct = s.crosstalk;
	cv::Mat out8(rgb.size(), CV_8UC3);
	// Output encoding: linear → gamma → 8 bit, as a table over the ADC codes.
	std::vector<uint8_t> lut(size_t(maxv) + 1);
	for (int i = 0; i <= maxv; i++)
		lut[size_t(i)] = cv::saturate_cast<uint8_t>(255.0 * std::pow(double(i) / maxv, 1.0 / s.gamma));
	auto adc = [&](double v, uint64_t index) {
		double e = std::max(0.0, v * exposure) * fw;
		if (ns > 0)
			e += ns * (std::sqrt(e) * internal::gaussian(key, 2 * index) +
				   s.read_noise_e * internal::gaussian(key, 2 * index + 1));
		return int(std::clamp(std::lround(e / fw * maxv), 0L, long(maxv)));
	};
	if (!s.bayer) {
		cv::parallel_for_(cv::Range(0, rgb.rows), [&](const cv::Range &r) {
			for (int y = r.start; y < r.end; y++)
				for (int x = 0; x < rgb.cols; x++) {
					cv::Vec3f c = ct * rgb.at<cv::Vec3f>(y, x);
					uint64_t idx = (uint64_t(y) * uint64_t(rgb.cols) + uint64_t(x)) * 3;
					cv::Vec3b &o = out8.at<cv::Vec3b>(y, x);
					for (int k = 0; k < 3; k++)
						o[2 - k] = lut[size_t(adc(c[k], idx + uint64_t(k)))];
				}
		});
		return out8;
	}
	// RGGB mosaic: R at (even row, even col), B at (odd, odd), G elsewhere.
	cv::Mat raw(rgb.size(), CV_16U);
	const int shift = 16 - s.adc_bits;
	cv::parallel_for_(cv::Range(0, rgb.rows), [&](const cv::Range &r) {
		for (int y = r.start; y < r.end; y++)
			for (int x = 0; x < rgb.cols; x++) {
				int ch = (y & 1) == 0 ? ((x & 1) == 0 ? 0 : 1) : ((x & 1) == 0 ? 1 : 2);
				cv::Vec3f c = ct * rgb.at<cv::Vec3f>(y, x);
				uint64_t idx = uint64_t(y) * uint64_t(rgb.cols) + uint64_t(x);
				raw.at<uint16_t>(y, x) = uint16_t(adc(c[ch], idx) << shift);
			}
	});
	// OpenCV names Bayer patterns by the second row's first two pixels: RGGB is "BayerBG".
	cv::Mat bgr16;
	cv::demosaicing(raw, bgr16, cv::COLOR_BayerBG2BGR);
	cv::parallel_for_(cv::Range(0, rgb.rows), [&](const cv::Range &r) {
		for (int y = r.start; y < r.end; y++)
			for (int x = 0; x < rgb.cols; x++) {
				const cv::Vec3w &v = bgr16.at<cv::Vec3w>(y, x);
				cv::Vec3b &o = out8.at<cv::Vec3b>(y, x);
				for (int k = 0; k < 3; k++)
					o[k] = lut[size_t(v[k] >> shift)];
			}
	});
	return out8;
}

} // namespace

Status render_views(const Rig &rig, const std::vector<Surface> &surfaces, const cv::Mat &slide,
		    const RenderOptions &options, uint64_t seed, RenderResult *ret_result)
{
	if (rig.cameras.empty())
		return Status::error(-EINVAL, "render: the rig has no cameras");
	if (surfaces.empty())
		return Status::error(-EINVAL, "render: no surfaces");
	if (rig.supersample < 1 || rig.supersample > 8)
		return Status::error(-EINVAL, "render: supersample must be 1..8");
	const bool lit = options.pattern && !rig.projectors.empty();
	if (lit && (slide.empty() || slide.type() != CV_8UC3))
		return Status::error(-EINVAL, "render: the slide must be a non-empty 8-bit BGR image");
	if (!options.projectors_on.empty() && options.projectors_on.size() != rig.projectors.size())
		return Status::error(-EINVAL, "render: projectors_on must name every projector");
	for (const SimCamera &c : rig.cameras)
		if (c.model.size.width < 1 || c.model.size.height < 1)
			return Status::error(-EINVAL, "render: camera " + c.name + " has no size");
	for (size_t i = 0; i < surfaces.size(); i++) {
		const Surface &s = surfaces[i];
		if (!s.texture.empty() && s.texture.depth() != CV_8U && s.texture.depth() != CV_16U)
			return Status::error(-EINVAL, "render: surface " + std::to_string(i) +
							      " texture must be 8- or 16-bit");
		if (!s.texture.empty() && s.texture.channels() != 3 && s.texture.channels() != 1)
			return Status::error(-EINVAL, "render: surface " + std::to_string(i) +
							      " texture must have 1 or 3 channels");
	}
	Tracer tracer;
	Status st = build_tracer(surfaces, &tracer);
	if (!st.ok())
		return st;

	for (const SimProjector &p : rig.projectors)
		if (!p.mask.empty() && p.mask.size() < 3)
			return Status::error(-EINVAL, "render: projector " + p.name + " mask needs at least 3 points");
	// Slide stacks, shared by unmasked projectors with the same size and gamma (a masked one
	// has its own: key -1 - j).
	std::map<std::tuple<int, int, double, int>, SlideStack> stacks;
	std::vector<const SlideStack *> slides(rig.projectors.size(), nullptr);
	if (lit)
		for (size_t j = 0; j < rig.projectors.size(); j++) {
			const SimProjector &p = rig.projectors[j];
			auto key = std::make_tuple(p.size.width, p.size.height, p.gamma, p.mask.empty() ? 0 : -1 - int(j));
			auto it = stacks.find(key);
			if (it == stacks.end())
				it = stacks.emplace(key, SlideStack::make(slide, p.size, p.gamma, p.mask)).first;
			slides[j] = &it->second;
		}
	std::vector<cv::Mat> textures;
	for (const Surface &s : surfaces)
		textures.push_back(linear_texture(s.texture));

	RenderOptions opts = options;
	opts.pattern = lit;
	Renderer renderer(rig, surfaces, tracer, slides, textures, opts);
	RenderResult result;
	const int ss = rig.supersample;
	for (size_t ci = 0; ci < rig.cameras.size(); ci++) {
		const SimCamera &cam = rig.cameras[ci];
		const CameraModel &cm = cam.model;
		const int W = cm.size.width, H = cm.size.height;
		// Ray directions for every sample: undistort the pixel positions.
		std::vector<cv::Point2f> px;
		px.reserve(size_t(W) * size_t(H) * size_t(ss * ss));
		for (int y = 0; y < H; y++)
			for (int x = 0; x < W; x++)
				for (int sy = 0; sy < ss; sy++)
					for (int sx = 0; sx < ss; sx++)
						px.emplace_back(float(x + (sx + 0.5) / ss - 0.5),
								float(y + (sy + 0.5) / ss - 0.5));
		std::vector<cv::Point2f> norm;
		cv::undistortPoints(px, norm, cm.K, cm.dist, cv::noArray(), cv::noArray(),
				    cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 1e-9));
		px.clear();
		px.shrink_to_fit();
		const bool centre_ray = options.truth && ss % 2 == 0; // no sample at the pixel centre
		std::vector<cv::Point2f> centre_norm;
		if (centre_ray) {
			std::vector<cv::Point2f> c;
			c.reserve(size_t(W) * size_t(H));
			for (int y = 0; y < H; y++)
				for (int x = 0; x < W; x++)
					c.emplace_back(float(x), float(y));
			cv::undistortPoints(c, centre_norm, cm.K, cm.dist, cv::noArray(), cv::noArray(),
					    cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 1e-9));
		}

		// Samples nearer than this belong to the near layer (the head), the rest to the far one.
		const double near_limit = cam.focus_mm + 300;
		cv::Mat pat_n(H, W, CV_32FC3), pat_f(H, W, CV_32FC3), tex_n(H, W, CV_32FC3),
			tex_f(H, W, CV_32FC3), alpha(H, W, CV_32F), sigma(H, W, CV_32F);
		ViewTruth truth;
		if (options.truth) {
			truth.depth.create(H, W, CV_32F);
			truth.surface.create(H, W, CV_8U);
			truth.slide_xy.create(H, W, CV_32FC2);
			truth.projector.create(H, W, CV_8S);
		}
		const cv::Vec3d origin = cm.centre();
		const cv::Matx33d Rt = cm.R.t();
		const float inv = 1.f / float(ss * ss);
		auto coc = [&](double z) {
			return float(std::hypot(cam.blur_px, cam.defocus_px_per_100mm * std::fabs(z - cam.focus_mm) / 100));
		};
		std::vector<double> far_depth_sum(size_t(H), 0.0);
		std::vector<long> far_depth_n(size_t(H), 0);
		cv::parallel_for_(cv::Range(0, H), [&](const cv::Range &r) {
			for (int y = r.start; y < r.end; y++)
				for (int x = 0; x < W; x++) {
					cv::Vec3f pn(0, 0, 0), pf(0, 0, 0), tn(0, 0, 0), tf(0, 0, 0);
					float dsum = 0;
					int nn = 0;
					size_t base = (size_t(y) * size_t(W) + size_t(x)) * size_t(ss * ss);
					Shaded centre;
					for (int k = 0; k < ss * ss; k++) {
						const cv::Point2f &n = norm[base + size_t(k)];
						cv::Vec3d d = cv::normalize(Rt * cv::Vec3d(n.x, n.y, 1));
						Shaded sh = renderer.shade(origin, d, cm);
						if (sh.depth > 0 && sh.depth < near_limit) {
							pn += sh.pattern;
							tn += sh.texture;
							dsum += sh.depth;
							nn++;
						} else {
							pf += sh.pattern;
							tf += sh.texture;
							far_depth_sum[size_t(y)] += sh.depth > 0 ? sh.depth : cam.focus_mm + 1000;
							far_depth_n[size_t(y)]++;
						}
						if (k == (ss * ss) / 2)
							centre = sh;
					}
					pat_n.at<cv::Vec3f>(y, x) = pn * inv;
					pat_f.at<cv::Vec3f>(y, x) = pf * inv;
					tex_n.at<cv::Vec3f>(y, x) = tn * inv;
					tex_f.at<cv::Vec3f>(y, x) = tf * inv;
					alpha.at<float>(y, x) = float(nn) * inv;
					sigma.at<float>(y, x) = coc(nn ? dsum / float(nn) : cam.focus_mm);
					if (!options.truth)
						continue;
					if (centre_ray) {
						const cv::Point2f &n = centre_norm[size_t(y) * size_t(W) + size_t(x)];
						centre = renderer.shade(origin, cv::normalize(Rt * cv::Vec3d(n.x, n.y, 1)), cm);
					}
					truth.depth.at<float>(y, x) = centre.depth;
					truth.surface.at<uint8_t>(y, x) = centre.surface;
					truth.slide_xy.at<cv::Vec2f>(y, x) = centre.slide_xy;
					truth.projector.at<int8_t>(y, x) = centre.projector;
				}
		});
		double fsum = 0;
		long fn = 0;
		for (int y = 0; y < H; y++) {
			fsum += far_depth_sum[size_t(y)];
			fn += far_depth_n[size_t(y)];
		}
		const double far_sigma = fn ? coc(fsum / double(fn)) : 0.0;
		const uint64_t key = internal::mix64(seed ^ internal::mix64(ci + 1));
		if (options.pattern)
			result.frames.push_back(sensor(defocus(pat_n, alpha, sigma, pat_f, far_sigma), rig.sensor, cam.exposure,
						       options.noise, internal::mix64(key ^ 0x9a77e5ULL)));
		if (options.texture)
			result.textures.push_back(sensor(defocus(tex_n, alpha, sigma, tex_f, far_sigma), rig.sensor, cam.exposure,
							 options.noise, internal::mix64(key ^ 0x7e87eeULL)));
		if (options.truth)
			result.truth.push_back(truth);
	}
	*ret_result = std::move(result);
	return Status();
}

} // namespace facescan::sim
