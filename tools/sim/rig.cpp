// The rig: loading the YAML description, placing devices, scaling, the calibration it implies.
#include "sim/sim.hpp"

#include <opencv2/core/persistence.hpp>

#include <cmath>
#include <fstream>
#include <set>

namespace facescan::sim {

// The text of tools/sim/rigs/default.yaml (tests/sim/test_sim_rig checks they stay equal).
extern const char *const kDefaultRigYaml;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Parser {
	std::string file;
	Status status;

	bool fail(const std::string &key, const std::string &why)
	{
		if (status.ok())
			status = Status::error(-EINVAL, file + ": " + key + ": " + why);
		return false;
	}

	bool check_keys(const cv::FileNode &node, const std::string &where,
			const std::set<std::string> &allowed)
	{
		if (!node.isMap())
			return fail(where, "expected a map");
		for (const std::string &k : node.keys())
			if (!allowed.count(k))
				return fail(where + "." + k, "unknown key");
		return true;
	}

	bool number(const cv::FileNode &node, const std::string &key, const std::string &where,
		    double *value, double lo = -1e300, double hi = 1e300)
	{
		cv::FileNode n = node[key];
		if (n.empty())
			return true;
		if (!n.isReal() && !n.isInt())
			return fail(where + "." + key, "expected a number");
		double v = double(n);
		if (!std::isfinite(v) || v < lo || v > hi)
			return fail(where + "." + key, "value " + std::to_string(v) + " out of range [" +
							       std::to_string(lo) + ", " + std::to_string(hi) + "]");
		*value = v;
		return true;
	}

	bool vec(const cv::FileNode &node, const std::string &key, const std::string &where,
		 size_t count, std::vector<double> *values, bool *present = nullptr)
	{
		cv::FileNode n = node[key];
		if (present)
			*present = !n.empty();
		if (n.empty())
			return true;
		if (!n.isSeq() || n.size() != count)
			return fail(where + "." + key, "expected a list of " + std::to_string(count) + " numbers");
		values->clear();
		for (size_t i = 0; i < count; i++) {
			cv::FileNode e = n[int(i)];
			if (!e.isReal() && !e.isInt())
				return fail(where + "." + key, "element " + std::to_string(i) + " is not a number");
			double v = double(e);
			if (!std::isfinite(v))
				return fail(where + "." + key, "element " + std::to_string(i) + " is not finite");
			values->push_back(v);
		}
		return true;
	}

	// The placement shared by cameras and projectors.
	struct Placement {
		double azimuth = 0, elevation = 0, distance = 550, roll = 0;
		std::vector<double> target = {0, 0, 0};
		std::vector<double> size, focal, principal, R, T;
		bool has_az = false, has_R = false, has_T = false;
	};

	bool placement(const cv::FileNode &node, const std::string &where, Placement *p)
	{
		p->has_az = !node["azimuth_deg"].empty();
		number(node, "azimuth_deg", where, &p->azimuth, -360, 360);
		number(node, "elevation_deg", where, &p->elevation, -89, 89);
		number(node, "distance_mm", where, &p->distance, 1, 1e5);
		number(node, "roll_deg", where, &p->roll, -360, 360);
		vec(node, "target_mm", where, 3, &p->target);
		vec(node, "R", where, 9, &p->R, &p->has_R);
		vec(node, "T", where, 3, &p->T, &p->has_T);
		bool has_size = false, has_focal = false;
		vec(node, "size", where, 2, &p->size, &has_size);
		vec(node, "focal_px", where, 2, &p->focal, &has_focal);
		vec(node, "principal_px", where, 2, &p->principal);
		if (!status.ok())
			return false;
		if (!has_size)
			return fail(where + ".size", "missing");
		if (!has_focal)
			return fail(where + ".focal_px", "missing");
		if (p->size[0] < 8 || p->size[1] < 8 || p->size[0] > 20000 || p->size[1] > 20000 ||
		    p->size[0] != std::floor(p->size[0]) || p->size[1] != std::floor(p->size[1]))
			return fail(where + ".size", "expected two integers in 8..20000");
		if (p->focal[0] <= 0 || p->focal[1] <= 0)
			return fail(where + ".focal_px", "must be positive");
		if (p->has_R != p->has_T)
			return fail(where + (p->has_R ? ".T" : ".R"), "R and T must be given together");
		if (!p->has_R && !p->has_az)
			return fail(where + ".azimuth_deg", "missing (give azimuth_deg or R and T)");
		if (p->has_R) {
			cv::Matx33d R(p->R.data());
			if (cv::norm(R * R.t() - cv::Matx33d::eye()) > 1e-6 || cv::determinant(R) < 0)
				return fail(where + ".R", "not a rotation matrix");
		}
		return true;
	}

	void pose(const Placement &p, cv::Matx33d *R, cv::Vec3d *T)
	{
		if (p.has_R) {
			*R = cv::Matx33d(p.R.data());
			*T = cv::Vec3d(p.T[0], p.T[1], p.T[2]);
			return;
		}
		cv::Vec3d target(p.target[0], p.target[1], p.target[2]);
		look_at(orbit_position(target, p.azimuth, p.elevation, p.distance), target, p.roll, R, T);
	}

	static cv::Matx33d intrinsics(const Placement &p)
	{
		double cx = p.principal.empty() ? (p.size[0] - 1) / 2 : p.principal[0];
		double cy = p.principal.empty() ? (p.size[1] - 1) / 2 : p.principal[1];
		return cv::Matx33d(p.focal[0], 0, cx, 0, p.focal[1], cy, 0, 0, 1);
	}

	bool camera(const cv::FileNode &node, const std::string &where, SimCamera *c)
	{
		if (!check_keys(node, where,
				{"name", "azimuth_deg", "elevation_deg", "distance_mm", "target_mm",
				 "roll_deg", "R", "T", "size", "focal_px", "principal_px", "dist",
				 "focus_mm", "blur_px", "defocus_px_per_100mm", "exposure"}))
			return false;
		Placement p;
		if (!placement(node, where, &p))
			return false;
		if (node["name"].isString())
			c->name = std::string(node["name"]);
		std::vector<double> dist;
		bool has_dist = false;
		vec(node, "dist", where, 5, &dist, &has_dist);
		number(node, "focus_mm", where, &c->focus_mm, 1, 1e5);
		number(node, "blur_px", where, &c->blur_px, 0, 50);
		number(node, "defocus_px_per_100mm", where, &c->defocus_px_per_100mm, 0, 50);
		number(node, "exposure", where, &c->exposure, 0, 1e4);
		if (!status.ok())
			return false;
		if (has_dist)
			for (int i = 0; i < 5; i++) {
				if (std::fabs(dist[size_t(i)]) > 2)
					return fail(where + ".dist", "coefficient out of range [-2, 2]");
				c->model.dist[i] = dist[size_t(i)];
			}
		c->model.size = cv::Size(int(p.size[0]), int(p.size[1]));
		c->model.K = intrinsics(p);
		pose(p, &c->model.R, &c->model.T);
		return true;
	}

	bool projector(const cv::FileNode &node, const std::string &where, SimProjector *pr)
	{
		if (!check_keys(node, where,
				{"name", "azimuth_deg", "elevation_deg", "distance_mm", "target_mm",
				 "roll_deg", "R", "T", "size", "focal_px", "principal_px", "power",
				 "focus_mm", "blur_px", "defocus_px_per_100mm", "gamma", "mask", "zone_mm"}))
			return false;
		Placement p;
		if (!placement(node, where, &p))
			return false;
		if (node["name"].isString())
			pr->name = std::string(node["name"]);
		number(node, "power", where, &pr->power, 0, 1e4);
		number(node, "focus_mm", where, &pr->focus_mm, 1, 1e5);
		number(node, "blur_px", where, &pr->blur_px, 0, 50);
		number(node, "defocus_px_per_100mm", where, &pr->defocus_px_per_100mm, 0, 50);
		number(node, "gamma", where, &pr->gamma, 0.1, 10);
		if (!status.ok())
			return false;
		pr->mask.clear();
		cv::FileNode mask = node["mask"];
		if (!mask.empty()) {
			if (!mask.isSeq() || mask.size() < 6 || mask.size() % 2 != 0)
				return fail(where + ".mask", "expected a polygon: a list x0, y0, x1, y1, ... of at least 3 points");
			for (size_t i = 0; i < mask.size(); i += 2) {
				cv::FileNode x = mask[int(i)], y = mask[int(i + 1)];
				if ((!x.isReal() && !x.isInt()) || (!y.isReal() && !y.isInt()) ||
				    !std::isfinite(double(x)) || !std::isfinite(double(y)))
					return fail(where + ".mask", "element " + std::to_string(i) + " is not a finite number");
				pr->mask.emplace_back(double(x), double(y));
			}
		}
		pr->size = cv::Size(int(p.size[0]), int(p.size[1]));
		pr->K = intrinsics(p);
		pose(p, &pr->R, &pr->T);
		std::vector<double> zone;
		bool has_zone = false;
		vec(node, "zone_mm", where, 2, &zone, &has_zone);
		if (!status.ok())
			return false;
		if (has_zone) {
			if (!mask.empty())
				return fail(where + ".zone_mm", "give mask or zone_mm, not both");
			if (!(zone[0] < zone[1]))
				return fail(where + ".zone_mm", "expected [x_lo, x_hi] with x_lo < x_hi");
			const double lo = zone[0] <= -1000 ? -INFINITY : zone[0], hi = zone[1] >= 1000 ? INFINITY : zone[1];
			Status st = zone_mask(*pr, lo, hi, &pr->mask);
			if (!st.ok())
				return fail(where + ".zone_mm", st.message());
		}
		return true;
	}

	bool sensor(const cv::FileNode &node, SensorModel *s)
	{
		if (!check_keys(node, "sensor",
				{"full_well_e", "read_noise_e", "adc_bits", "gamma", "crosstalk", "bayer",
				 "noise_scale"}))
			return false;
		double bits = s->adc_bits, bayer = s->bayer ? 1 : 0;
		number(node, "full_well_e", "sensor", &s->full_well_e, 1, 1e7);
		number(node, "read_noise_e", "sensor", &s->read_noise_e, 0, 1e5);
		number(node, "adc_bits", "sensor", &bits, 8, 16);
		number(node, "gamma", "sensor", &s->gamma, 0.1, 10);
		number(node, "bayer", "sensor", &bayer, 0, 1);
		number(node, "noise_scale", "sensor", &s->noise_scale, 0, 1000);
		std::vector<double> ct;
		bool has_ct = false;
		vec(node, "crosstalk", "sensor", 9, &ct, &has_ct);
		if (!status.ok())
			return false;
		if (bits != std::floor(bits))
			return fail("sensor.adc_bits", "expected an integer");
		if (bayer != 0 && bayer != 1)
			return fail("sensor.bayer", "expected 0 or 1");
		s->adc_bits = int(bits);
		s->bayer = bayer == 1;
		if (has_ct)
			s->crosstalk = cv::Matx33d(ct.data());
		return true;
	}

	bool lighting(const cv::FileNode &node, Lighting *l)
	{
		if (!check_keys(node, "lighting", {"ambient_pattern", "ambient_texture", "lights"}))
			return false;
		number(node, "ambient_pattern", "lighting", &l->ambient_pattern, 0, 100);
		number(node, "ambient_texture", "lighting", &l->ambient_texture, 0, 100);
		cv::FileNode lights = node["lights"];
		if (!lights.empty()) {
			if (!lights.isSeq())
				return fail("lighting.lights", "expected a list");
			l->lights.clear();
			for (size_t i = 0; i < lights.size(); i++) {
				std::string where = "lighting.lights[" + std::to_string(i) + "]";
				cv::FileNode n = lights[int(i)];
				if (!check_keys(n, where, {"azimuth_deg", "elevation_deg", "intensity"}))
					return false;
				DiffuseLight d;
				number(n, "azimuth_deg", where, &d.azimuth_deg, -360, 360);
				number(n, "elevation_deg", where, &d.elevation_deg, -90, 90);
				number(n, "intensity", where, &d.intensity, 0, 100);
				l->lights.push_back(d);
			}
		}
		return status.ok();
	}

	bool rig(const cv::FileNode &root, Rig *r)
	{
		if (!check_keys(root, "(top level)",
				{"cameras", "projectors", "sensor", "lighting", "supersample", "booth"}))
			return false;
		double ss = r->supersample;
		// `booth` records how a random booth was drawn (booth.yaml): for people, not the rig.
		number(root, "supersample", "(top level)", &ss, 1, 8);
		if (!status.ok())
			return false;
		if (ss != std::floor(ss))
			return fail("supersample", "expected an integer 1..8");
		r->supersample = int(ss);
		cv::FileNode cams = root["cameras"];
		if (!cams.empty()) {
			if (!cams.isSeq() || cams.size() == 0)
				return fail("cameras", "expected a non-empty list");
			r->cameras.assign(cams.size(), SimCamera());
			for (size_t i = 0; i < cams.size(); i++) {
				r->cameras[i].name = "cam" + std::to_string(i);
				if (!camera(cams[int(i)], "cameras[" + std::to_string(i) + "]", &r->cameras[i]))
					return false;
			}
		}
		cv::FileNode projs = root["projectors"];
		if (!projs.empty()) {
			if (!projs.isSeq())
				return fail("projectors", "expected a list");
			r->projectors.assign(projs.size(), SimProjector());
			for (size_t i = 0; i < projs.size(); i++) {
				r->projectors[i].name = "proj" + std::to_string(i);
				if (!projector(projs[int(i)], "projectors[" + std::to_string(i) + "]",
					       &r->projectors[i]))
					return false;
			}
		}
		if (!root["sensor"].empty() && !sensor(root["sensor"], &r->sensor))
			return false;
		if (!root["lighting"].empty() && !lighting(root["lighting"], &r->lighting))
			return false;
		return status.ok();
	}
};

Status parse_rig(const std::string &text, const std::string &name, const Rig &defaults,
		 Rig *ret_rig)
{
	Parser p;
	p.file = name;
	Rig rig = defaults;
	try {
		cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY |
						 cv::FileStorage::FORMAT_YAML);
		if (!fs.isOpened())
			return Status::error(-EINVAL, name + ": not a readable YAML file");
		if (!p.rig(fs.root(), &rig))
			return p.status;
	} catch (const cv::Exception &e) {
		return Status::error(-EINVAL, name + ": YAML parse error: " + e.msg);
	}
	*ret_rig = std::move(rig);
	return Status();
}

Rig builtin_defaults()
{
	Rig r;
	r.lighting.lights = {{-35, 20, 0.45}, {35, 20, 0.45}, {0, 60, 0.2}};
	return r;
}

} // namespace

Rig default_rig()
{
	Rig rig;
	// The embedded text is checked by a test; a parse failure here would be a build defect.
	Status st = parse_rig(kDefaultRigYaml, "default rig", builtin_defaults(), &rig);
	(void)st;
	return rig;
}

Status load_rig(const std::string &path, Rig *ret_rig)
{
	std::ifstream in(path, std::ios::binary);
	if (!in)
		return Status::error(-ENOENT, path + ": cannot open rig file");
	std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
	if (text.empty())
		return Status::error(-EINVAL, path + ": empty rig file");
	if (text.rfind("%YAML", 0) != 0)
		text = "%YAML:1.0\n---\n" + text;
	return parse_rig(text, path, default_rig(), ret_rig);
}

Status scale_rig(double scale, Rig *rig)
{
	if (!(scale > 0 && scale <= 4))
		return Status::error(-EINVAL, "scale " + std::to_string(scale) + " out of range (0, 4]");
	for (SimCamera &c : rig->cameras) {
		cv::Size s(int(std::lround(c.model.size.width * scale)),
			   int(std::lround(c.model.size.height * scale)));
		if (s.width < 8 || s.height < 8)
			return Status::error(-EINVAL, "scale " + std::to_string(scale) +
							      " makes camera " + c.name + " smaller than 8 px");
		double sx = double(s.width) / c.model.size.width;
		double sy = double(s.height) / c.model.size.height;
		cv::Matx33d &K = c.model.K;
		K(0, 0) *= sx;
		K(0, 1) *= sx;
		K(1, 1) *= sy;
		// Pixel centres: continuous x = pixel + 0.5 scales, so cx' = (cx + 0.5) * s - 0.5.
		K(0, 2) = (K(0, 2) + 0.5) * sx - 0.5;
		K(1, 2) = (K(1, 2) + 0.5) * sy - 0.5;
		c.model.size = s;
		c.blur_px *= std::sqrt(sx * sy);
		c.defocus_px_per_100mm *= std::sqrt(sx * sy);
	}
	return Status();
}

cv::Vec3d orbit_position(const cv::Vec3d &target, double azimuth_deg, double elevation_deg,
			 double distance_mm)
{
	double az = azimuth_deg * kPi / 180, el = elevation_deg * kPi / 180;
	return target + distance_mm * cv::Vec3d(std::sin(az) * std::cos(el), std::sin(el),
						std::cos(az) * std::cos(el));
}

void look_at(const cv::Vec3d &eye, const cv::Vec3d &target, double roll_deg, cv::Matx33d *ret_R,
	     cv::Vec3d *ret_T)
{
	cv::Vec3d z = cv::normalize(target - eye);
	cv::Vec3d up(0, 1, 0);
	if (std::fabs(z.dot(up)) > 0.999)
		up = cv::Vec3d(0, 0, -1);
	// Image y points down, so world +y (up) appears at the top of the image.
	cv::Vec3d x = cv::normalize(z.cross(up));
	cv::Vec3d y = z.cross(x);
	double r = roll_deg * kPi / 180, c = std::cos(r), s = std::sin(r);
	cv::Vec3d xr = c * x + s * y, yr = -s * x + c * y;
	cv::Matx33d R(xr[0], xr[1], xr[2], yr[0], yr[1], yr[2], z[0], z[1], z[2]);
	*ret_R = R;
	*ret_T = -(R * eye);
}

Calibration rig_calibration(const Rig &rig)
{
	Calibration cal;
	cal.id = "sim-rig";
	for (const SimCamera &c : rig.cameras)
		cal.cameras.push_back(c.model);
	return cal;
}

std::vector<CameraModel> projector_models(const Rig &rig)
{
	std::vector<CameraModel> out;
	for (const SimProjector &p : rig.projectors) {
		CameraModel m;
		m.K = p.K;
		m.R = p.R;
		m.T = p.T;
		m.size = p.size;
		out.push_back(m);
	}
	return out;
}

std::vector<std::vector<cv::Point2d>> projector_masks(const Rig &rig)
{
	std::vector<std::vector<cv::Point2d>> out;
	for (const SimProjector &p : rig.projectors)
		out.push_back(p.mask);
	return out;
}

namespace {

void write_pose(cv::FileStorage &fs, const cv::Matx33d &R, const cv::Vec3d &T, cv::Size size, const cv::Matx33d &K)
{
	fs << "R" << "[:";
	for (int i = 0; i < 9; i++)
		fs << R.val[i];
	fs << "]" << "T" << "[:" << T[0] << T[1] << T[2] << "]";
	fs << "size" << "[:" << size.width << size.height << "]";
	fs << "focal_px" << "[:" << K(0, 0) << K(1, 1) << "]";
	fs << "principal_px" << "[:" << K(0, 2) << K(1, 2) << "]";
}

} // namespace

Status write_rig(const std::string &path, const Rig &rig, const std::string &booth_text)
{
	std::string text;
	try {
		cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
		fs << "supersample" << rig.supersample;
		fs << "cameras" << "[";
		for (const SimCamera &c : rig.cameras) {
			fs << "{" << "name" << c.name;
			write_pose(fs, c.model.R, c.model.T, c.model.size, c.model.K);
			fs << "dist" << "[:";
			for (int i = 0; i < 5; i++)
				fs << c.model.dist[i];
			fs << "]" << "focus_mm" << c.focus_mm << "blur_px" << c.blur_px
			   << "defocus_px_per_100mm" << c.defocus_px_per_100mm << "exposure" << c.exposure << "}";
		}
		fs << "]" << "projectors" << "[";
		for (const SimProjector &p : rig.projectors) {
			fs << "{" << "name" << p.name;
			write_pose(fs, p.R, p.T, p.size, p.K);
			fs << "power" << p.power << "focus_mm" << p.focus_mm << "blur_px" << p.blur_px
			   << "defocus_px_per_100mm" << p.defocus_px_per_100mm << "gamma" << p.gamma;
			if (!p.mask.empty()) {
				fs << "mask" << "[:";
				for (const cv::Point2d &q : p.mask)
					fs << q.x << q.y;
				fs << "]";
			}
			fs << "}";
		}
		fs << "]";
		const SensorModel &s = rig.sensor;
		fs << "sensor" << "{" << "full_well_e" << s.full_well_e << "read_noise_e" << s.read_noise_e
		   << "adc_bits" << s.adc_bits << "gamma" << s.gamma << "crosstalk" << "[:";
		for (int i = 0; i < 9; i++)
			fs << s.crosstalk.val[i];
		fs << "]" << "bayer" << (s.bayer ? 1 : 0) << "noise_scale" << s.noise_scale << "}";
		const Lighting &l = rig.lighting;
		fs << "lighting" << "{" << "ambient_pattern" << l.ambient_pattern << "ambient_texture"
		   << l.ambient_texture << "lights" << "[";
		for (const DiffuseLight &d : l.lights)
			fs << "{:" << "azimuth_deg" << d.azimuth_deg << "elevation_deg" << d.elevation_deg
			   << "intensity" << d.intensity << "}";
		fs << "]" << "}";
		text = fs.releaseAndGetString();
	} catch (const cv::Exception &e) {
		return Status::error(-EINVAL, path + ": cannot serialise the rig: " + e.err);
	}
	if (!booth_text.empty())
		text += "booth:\n" + booth_text;
	return write_file_atomic(path, text.data(), text.size());
}

} // namespace facescan::sim
