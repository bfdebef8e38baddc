// Random booths: cameras, projectors (with or without slide masks), lighting, noise, the head's
// pose and the error of the calibration that is written, all drawn from booth_ranges().
#include "sim/internal.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace facescan::sim {

namespace {

// The booth's nominal aim: the default rig's camera target (the face's centre, in front of
// the head's origin).
const cv::Vec3d kTarget(0, -10, 40);
constexpr double kHeadHeightMm = 240; // crown to chin, for the cameras' framing
constexpr double kZoneDepthMm = 60;   // zone boundaries are vertical lines at this depth

// Draws from one counter-keyed stream: each call takes the next index.
struct Draw {
	uint64_t key;
	uint64_t i = 0;
	double operator()(const Interval &r) { return r.lo + (r.hi - r.lo) * internal::uniform01(key, i++); }
	double unit() { return internal::uniform01(key, i++); }
	double normal() { return internal::gaussian(key, i++); }
};

cv::Vec2d project(const SimProjector &p, const cv::Vec3d &x)
{
	cv::Vec3d u = p.K * (p.R * x + p.T);
	return cv::Vec2d(u[0] / u[2], u[1] / u[2]);
}

// Sutherland-Hodgman: keeps the part of `poly` where a*x + b*y + c >= 0.
std::vector<cv::Point2d> clip(const std::vector<cv::Point2d> &poly, double a, double b, double c)
{
	std::vector<cv::Point2d> out;
	for (size_t i = 0; i < poly.size(); i++) {
		const cv::Point2d &p = poly[i], &q = poly[(i + 1) % poly.size()];
		double fp = a * p.x + b * p.y + c, fq = a * q.x + b * q.y + c;
		if (fp >= 0)
			out.push_back(p);
		if ((fp >= 0) != (fq >= 0))
			out.push_back(p + (q - p) * (fp / (fp - fq)));
	}
	return out;
}

// The slide polygon of projector `p` lighting the world half x >= x0 (keep_greater) or
// x <= x0: the slide is clipped by the image of the vertical line x = x0 at the face depth.
std::vector<cv::Point2d> clip_to_half(const SimProjector &p, const std::vector<cv::Point2d> &poly, double x0,
				      bool keep_greater)
{
	cv::Vec2d a = project(p, cv::Vec3d(x0, -150, kZoneDepthMm)), b = project(p, cv::Vec3d(x0, 150, kZoneDepthMm));
	cv::Vec2d in = project(p, cv::Vec3d(x0 + (keep_greater ? 40 : -40), 0, kZoneDepthMm));
	// Line through a and b: n . x + c = 0, signed so that the kept side is positive.
	double nx = -(b[1] - a[1]), ny = b[0] - a[0];
	double c = -(nx * a[0] + ny * a[1]);
	if (nx * in[0] + ny * in[1] + c < 0)
		nx = -nx, ny = -ny, c = -c;
	return clip(poly, nx, ny, c);
}

} // namespace

Status zone_mask(const SimProjector &p, double x_lo_mm, double x_hi_mm, std::vector<cv::Point2d> *ret_mask)
{
	const double W = p.size.width - 0.5, H = p.size.height - 0.5;
	std::vector<cv::Point2d> poly = {{-0.5, -0.5}, {W, -0.5}, {W, H}, {-0.5, H}};
	if (std::isfinite(x_lo_mm))
		poly = clip_to_half(p, poly, x_lo_mm, true);
	if (std::isfinite(x_hi_mm) && poly.size() >= 3)
		poly = clip_to_half(p, poly, x_hi_mm, false);
	if (poly.size() < 3)
		return Status::error(-EINVAL, "zone mask: projector " + p.name + " does not reach its zone");
	*ret_mask = std::move(poly);
	return Status();
}

const BoothRanges &booth_ranges()
{
	static const BoothRanges r;
	return r;
}

Status random_booth(uint64_t seed, double slide_pitch_px, RandomBooth *ret_booth)
{
	if (!(slide_pitch_px > 0))
		return Status::error(-EINVAL, "random booth: the slide pitch must be positive");
	const BoothRanges &R = booth_ranges();
	Draw d{internal::mix64(seed ^ 0xb0074a11ULL)};
	RandomBooth b;
	b.seed = seed;
	Rig rig = default_rig(); // sensor's crosstalk, gamma, ADC; lens focus/defocus defaults

	// Cameras: azimuths inside their bands with consecutive gaps inside cam_gap_deg (redrawn
	// until they are; the bands make that quick).
	double az[4];
	for (int attempt = 0;; attempt++) {
		for (int i = 0; i < 4; i++)
			az[i] = d(R.cam_azimuth_deg[i]);
		bool ok = true;
		for (int i = 0; i < 3; i++)
			ok &= az[i + 1] - az[i] >= R.cam_gap_deg.lo && az[i + 1] - az[i] <= R.cam_gap_deg.hi;
		if (ok)
			break;
		if (attempt > 1000)
			return Status::error(-EINVAL, "random booth: camera bands and gaps are inconsistent");
	}
	static const double aspects[3] = {4.0 / 3, 5.0 / 4, 16.0 / 10};
	rig.cameras.assign(4, SimCamera());
	for (int i = 0; i < 4; i++) {
		SimCamera &c = rig.cameras[size_t(i)];
		c.name = "cam" + std::to_string(i);
		const double el = d(R.cam_elevation_deg), dist = d(R.cam_distance_mm), roll = d(R.cam_roll_deg);
		const cv::Vec3d target = kTarget + cv::Vec3d(d(R.cam_target_jitter_mm), d(R.cam_target_jitter_mm),
							      d(R.cam_target_jitter_mm));
		const int w = 8 * int(std::lround(d(R.cam_width_px) / 8));
		const double aspect = aspects[std::min(2, int(d.unit() * 3))];
		const int h = 2 * int(std::lround(w / aspect / 2));
		const double f = d(R.cam_fill) * h * dist / kHeadHeightMm;
		const double fy = f * (1 + 0.002 * (d.unit() - 0.5));
		const double cx = (w - 1) / 2.0 + w * d(R.cam_principal_offset);
		const double cy = (h - 1) / 2.0 + h * d(R.cam_principal_offset);
		c.model.size = cv::Size(w, h);
		c.model.K = cv::Matx33d(f, 0, cx, 0, fy, cy, 0, 0, 1);
		c.model.dist = cv::Vec<double, 5>(d(R.cam_k1), d(R.cam_k2), d(R.cam_p), d(R.cam_p), 0);
		look_at(orbit_position(target, az[i], el, dist), target, roll, &c.model.R, &c.model.T);
		c.focus_mm = dist;
		c.blur_px = d(R.cam_blur_px);
		c.exposure = d(R.cam_exposure);
		b.cam_azimuth_deg.push_back(az[i]);
		b.cam_elevation_deg.push_back(el);
		b.cam_distance_mm.push_back(dist);
	}

	// Projectors.
	b.masked = d.unit() < R.masked_probability;
	b.zone_left_mm = d(R.zone_left_mm);
	b.zone_right_mm = d(R.zone_right_mm);
	b.zone_overlap_mm = d(R.zone_overlap_mm);
	const double aim_y = d(R.proj_aim_y_mm), aim_z = d(R.proj_aim_z_mm);
	rig.projectors.assign(3, SimProjector());
	for (int j = 0; j < 3; j++) {
		SimProjector &p = rig.projectors[size_t(j)];
		p.name = "proj" + std::to_string(j);
		p.size = cv::Size(1024, 768);
		const double paz = d(R.proj_azimuth_deg[j]), pel = d(R.proj_elevation_deg);
		const double pdist = d(R.proj_distance_mm), pitch = d(R.proj_pitch_mm);
		const double roll = 90.0 * std::min(3, int(d.unit() * 4)) + d(R.proj_roll_extra_deg);
		double ax = d(R.proj_aim_x_mm[j]);
		const double outer = d(R.zone_aim_outer_mm), centre = d(R.zone_aim_centre_mm);
		if (b.masked)
			ax = j == 0 ? b.zone_left_mm - outer
			     : j == 2 ? b.zone_right_mm + outer
				      : (b.zone_left_mm + b.zone_right_mm) / 2 + centre;
		const cv::Vec3d target(ax, aim_y + 10 * (d.unit() - 0.5), aim_z);
		const cv::Vec3d eye = orbit_position(target, paz, pel, pdist);
		look_at(eye, target, roll, &p.R, &p.T);
		const double f = slide_pitch_px * pdist / pitch;
		p.K = cv::Matx33d(f, 0, (p.size.width - 1) / 2.0, 0, f, (p.size.height - 1) / 2.0, 0, 0, 1);
		p.power = d(R.proj_face_power) * (pdist / 500) * (pdist / 500);
		p.focus_mm = pdist;
		b.proj_azimuth_deg.push_back(paz);
		b.proj_elevation_deg.push_back(pel);
		b.proj_distance_mm.push_back(pdist);
		b.proj_roll_deg.push_back(roll);
		b.proj_pitch_mm.push_back(pitch);
	}
	if (b.masked)
		for (int j = 0; j < 3; j++) {
			SimProjector &p = rig.projectors[size_t(j)];
			const double o = b.zone_overlap_mm, inf = INFINITY;
			const double lo = j == 0 ? -inf : j == 1 ? b.zone_left_mm - o : b.zone_right_mm - o;
			const double hi = j == 0 ? b.zone_left_mm + o : j == 1 ? b.zone_right_mm + o : inf;
			Status st = zone_mask(p, lo, hi, &p.mask);
			if (!st.ok())
				return st;
		}

	// Lighting and sensor.
	rig.lighting.ambient_pattern = d(R.ambient_pattern);
	rig.lighting.ambient_texture = d(R.ambient_texture);
	rig.lighting.lights = {{-d(R.softbox_azimuth_deg), d(R.softbox_elevation_deg), d(R.softbox_intensity)},
			       {d(R.softbox_azimuth_deg), d(R.softbox_elevation_deg), d(R.softbox_intensity)},
			       {0, 60, d(R.toplight_intensity)}};
	rig.sensor.read_noise_e = d(R.read_noise_e);
	rig.sensor.full_well_e = d(R.full_well_e);
	b.noise_scale = d(R.noise_scale);

	// The head's pose.
	b.head_offset_mm = cv::Vec3d(d(R.head_offset_mm), d(R.head_offset_mm), d(R.head_offset_mm));
	b.head_yaw_deg = d(R.head_yaw_deg);
	b.head_pitch_deg = d(R.head_pitch_deg);
	b.head_roll_deg = d(R.head_roll_deg);
	for (int i = 0; i < 4; i++)
		b.calibration_error_px.push_back(d(R.calibration_error_px));
	b.rig = std::move(rig);
	*ret_booth = std::move(b);
	return Status();
}

void apply_head_pose(const RandomBooth &booth, Scene *scene)
{
	scene->position = booth.head_offset_mm;
	scene->yaw_deg = booth.head_yaw_deg;
	scene->pitch_deg = booth.head_pitch_deg;
	scene->roll_deg = booth.head_roll_deg;
	scene->noise_scale = booth.noise_scale;
}

double reprojection_rms(const CameraModel &a, const CameraModel &b, const std::vector<cv::Point3d> &points)
{
	std::vector<cv::Point3d> in;
	for (const cv::Point3d &p : points) {
		cv::Vec3d xa = a.R * cv::Vec3d(p) + a.T, xb = b.R * cv::Vec3d(p) + b.T;
		if (xa[2] < 10 || xb[2] < 10)
			continue;
		in.push_back(p);
	}
	if (in.size() < 20)
		return -1;
	auto proj = [&](const CameraModel &c, std::vector<cv::Point2d> *out) {
		cv::Matx31d r;
		cv::Rodrigues(c.R, r);
		cv::projectPoints(in, r, cv::Vec3d(c.T), c.K, c.dist, *out);
	};
	std::vector<cv::Point2d> pa, pb;
	proj(a, &pa);
	proj(b, &pb);
	double ss = 0;
	size_t n = 0;
	for (size_t i = 0; i < in.size(); i++) {
		if (pa[i].x < 0 || pa[i].y < 0 || pa[i].x > a.size.width - 1 || pa[i].y > a.size.height - 1)
			continue;
		ss += (pa[i].x - pb[i].x) * (pa[i].x - pb[i].x) + (pa[i].y - pb[i].y) * (pa[i].y - pb[i].y);
		n++;
	}
	return n < 20 ? -1 : std::sqrt(ss / double(n));
}

Status perturb_calibration(const Calibration &truth, const std::vector<double> &rms_px,
			   const std::vector<cv::Point3d> &points, uint64_t seed, Calibration *ret_calibration,
			   std::vector<double> *ret_rms_px)
{
	if (rms_px.size() != truth.cameras.size())
		return Status::error(-EINVAL, "perturb calibration: one target per camera needed");
	Calibration out = truth;
	std::vector<double> reached;
	for (size_t i = 0; i < truth.cameras.size(); i++) {
		const CameraModel &t = truth.cameras[i];
		if (!(rms_px[i] >= 0 && rms_px[i] < 50))
			return Status::error(-EINVAL, "perturb calibration: target out of range [0, 50) px");
		Draw d{internal::mix64(seed ^ internal::mix64(0xca11b000ULL + i))};
		// A direction in parameter space, each parameter at the scale a good calibration
		// leaves it uncertain: fx fy (1e-3 relative), cx cy (1 px), k1 k2 (2e-3), p1 p2
		// (2e-4), rotation (2e-4 rad per axis), translation (0.1 mm per axis).
		double dir[14];
		for (double &v : dir)
			v = d.normal();
		auto apply = [&](double s) {
			CameraModel c = t;
			c.K(0, 0) *= 1 + s * 1e-3 * dir[0];
			c.K(1, 1) *= 1 + s * 1e-3 * dir[1];
			c.K(0, 2) += s * dir[2];
			c.K(1, 2) += s * dir[3];
			c.dist[0] += s * 2e-3 * dir[4];
			c.dist[1] += s * 2e-3 * dir[5];
			c.dist[2] += s * 2e-4 * dir[6];
			c.dist[3] += s * 2e-4 * dir[7];
			cv::Matx33d dR;
			cv::Rodrigues(cv::Vec3d(dir[8], dir[9], dir[10]) * (s * 2e-4), dR);
			c.R = dR * t.R;
			c.T = dR * t.T + cv::Vec3d(dir[11], dir[12], dir[13]) * (s * 0.1);
			return c;
		};
		double s = 1, r = reprojection_rms(t, apply(s), points);
		if (r < 0)
			return Status::error(-EINVAL, "perturb calibration: camera " + std::to_string(i) +
							      " sees fewer than 20 of the points");
		CameraModel c = t;
		if (rms_px[i] > 0) {
			// The displacement is nearly linear in s: a few secant steps reach the target.
			for (int it = 0; it < 6 && std::fabs(r - rms_px[i]) > 0.002 * rms_px[i]; it++) {
				s *= rms_px[i] / std::max(r, 1e-9);
				r = reprojection_rms(t, apply(s), points);
			}
			c = apply(s);
		} else {
			r = 0;
		}
		out.cameras[i] = c;
		reached.push_back(r);
	}
	out.id = truth.id.empty() ? "sim-rig (with calibration error)" : truth.id + " (with calibration error)";
	*ret_calibration = std::move(out);
	if (ret_rms_px)
		*ret_rms_px = std::move(reached);
	return Status();
}

std::string booth_yaml(const RandomBooth &b, const std::vector<double> &rms_px)
{
	std::string text;
	cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
	auto list = [&](const char *key, const std::vector<double> &v) {
		fs << key << "[:";
		for (double x : v)
			fs << x;
		fs << "]";
	};
	fs << "seed" << std::to_string(b.seed);
	fs << "mode" << (b.masked ? "masked" : "overlapping");
	if (b.masked)
		fs << "zone_left_mm" << b.zone_left_mm << "zone_right_mm" << b.zone_right_mm << "zone_overlap_mm"
		   << b.zone_overlap_mm;
	list("cam_azimuth_deg", b.cam_azimuth_deg);
	list("cam_elevation_deg", b.cam_elevation_deg);
	list("cam_distance_mm", b.cam_distance_mm);
	list("proj_azimuth_deg", b.proj_azimuth_deg);
	list("proj_elevation_deg", b.proj_elevation_deg);
	list("proj_distance_mm", b.proj_distance_mm);
	list("proj_roll_deg", b.proj_roll_deg);
	list("proj_pitch_mm", b.proj_pitch_mm);
	list("head_offset_mm", {b.head_offset_mm[0], b.head_offset_mm[1], b.head_offset_mm[2]});
	fs << "head_yaw_deg" << b.head_yaw_deg << "head_pitch_deg" << b.head_pitch_deg << "head_roll_deg"
	   << b.head_roll_deg << "noise_scale" << b.noise_scale;
	list("calibration_error_target_px", b.calibration_error_px);
	list("calibration_error_px", rms_px);
	text = fs.releaseAndGetString();
	// Indent under `booth:` (drop the %YAML header and the document marker).
	std::istringstream in(text);
	std::string line, out;
	while (std::getline(in, line)) {
		if (line.rfind("%YAML", 0) == 0 || line == "---" || line.empty())
			continue;
		out += "  " + line + "\n";
	}
	return out;
}

} // namespace facescan::sim
