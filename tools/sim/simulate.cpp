// The booth: named scenes, and rig + scene + pattern → capture set + ground truth.
#include "sim/internal.hpp"

#include <opencv2/imgproc.hpp>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <cmath>

#include <unistd.h>

namespace facescan::sim {

std::vector<std::string> scene_names()
{
	return {"default", "turned", "noisy", "dark"};
}

Status scene_by_name(const std::string &name, Scene *ret_scene)
{
	Scene s;
	s.name = name;
	if (name == "default") {
	} else if (name == "turned") {
		s.yaw_deg = 15;
	} else if (name == "noisy") {
		s.noise_scale = 4;
	} else if (name == "dark") {
		s.skin = cv::Vec3f(0.23f, 0.13f, 0.085f);
	} else {
		std::string all;
		for (const std::string &n : scene_names())
			all += (all.empty() ? "" : ", ") + n;
		return Status::error(-EINVAL, "unknown scene '" + name + "' (scenes: " + all + ")");
	}
	*ret_scene = s;
	return Status();
}

// The booth's wall: an inward-facing cylinder about +y around the head.
static Mesh make_booth_wall(double radius, double height)
{
	Mesh m;
	const int seg = 256;
	for (int i = 0; i <= seg; i++) {
		double a = 2 * M_PI * i / seg;
		cv::Vec3f n(float(-std::sin(a)), 0.f, float(-std::cos(a)));
		for (double y : {-height / 2, height / 2}) {
			m.vertices.push_back(cv::Vec3f(float(radius * std::sin(a)), float(y - 100), float(radius * std::cos(a))));
			m.normals.push_back(n);
		}
	}
	for (int i = 0; i < seg; i++) {
		int a = 2 * i, b = a + 1, c = a + 2, d = a + 3;
		m.triangles.push_back(cv::Vec3i(a, c, b));
		m.triangles.push_back(cv::Vec3i(b, c, d));
	}
	return m;
}

cv::Matx33d internal::head_rotation(double yaw_deg, double pitch_deg, double roll_deg)
{
	double y = yaw_deg * M_PI / 180, p = pitch_deg * M_PI / 180;
	cv::Matx33d Ry(std::cos(y), 0, std::sin(y), 0, 1, 0, -std::sin(y), 0, std::cos(y));
	cv::Matx33d Rx(1, 0, 0, 0, std::cos(p), -std::sin(p), 0, std::sin(p), std::cos(p));
	if (roll_deg == 0) // exactly the rotation scenes without a roll have always had
		return Ry * Rx;
	double r = roll_deg * M_PI / 180;
	cv::Matx33d Rz(std::cos(r), -std::sin(r), 0, std::sin(r), std::cos(r), 0, 0, 0, 1);
	return Ry * Rx * Rz;
}

Status simulate(const Rig &rig, const Scene &scene, const Pattern &pattern, uint64_t seed,
		CaptureSet *ret_set, SimTruth *ret_truth, const SimOptions &options)
{
	auto t0 = std::chrono::steady_clock::now();
	if (rig.cameras.empty())
		return Status::error(-EINVAL, "simulate: the rig has no cameras");
	if (!(scene.noise_scale >= 0 && scene.noise_scale <= 1000))
		return Status::error(-EINVAL, "simulate: scene noise_scale out of range");
	Surface head;
	Status st = make_head(scene.head, scene.skin, &head.mesh);
	if (!st.ok())
		return st;
	// A scanned head is placed in the canonical head's frame unscaled (scan_head.cpp), so its
	// face is the canonical shape's region.
	HeadSpec face_spec = scene.head;
	if (!face_spec.scan_dir.empty())
		face_spec.shape = HeadShape();
	std::vector<char> face = face_region(face_spec, head.mesh);
	transform_mesh(internal::head_rotation(scene.yaw_deg, scene.pitch_deg, scene.roll_deg), scene.position, &head.mesh);
	head.id = 1;
	head.specular = 0.06f; // the sheen of skin
	head.shininess = 24;
	std::vector<Surface> surfaces{head};
	if (std::isfinite(scene.backdrop_radius_mm)) {
		if (scene.backdrop_radius_mm < 200)
			return Status::error(-EINVAL, "simulate: backdrop radius must be at least 200 mm");
		Surface back;
		back.mesh = make_booth_wall(scene.backdrop_radius_mm, 2400);
		back.albedo = scene.backdrop_albedo;
		back.id = 2;
		surfaces.push_back(back);
	}
	Rig r = rig;
	r.sensor.noise_scale *= scene.noise_scale;
	RenderOptions ro;
	ro.texture = options.texture_frames;
	ro.truth = options.truth_maps;
	cv::Mat slide = rig.projectors.empty() ? cv::Mat() : render_slide(pattern);
	RenderResult res;
	st = render_views(r, surfaces, slide, ro, seed, &res);
	if (!st.ok())
		return st;
	double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
	if (ret_set) {
		CaptureSet set;
		set.calibration = rig_calibration(rig);
		set.frames = std::move(res.frames);
		set.textures = std::move(res.textures);
		set.meta.scan_id = "sim-" + scene.name + "-" + std::to_string(seed);
		set.meta.pattern_id = pattern.id;
		set.meta.timestamps_ns.assign(rig.cameras.size(), 0.0);
		for (const SimCamera &c : rig.cameras)
			set.meta.exposure_us.push_back(8000.0 * c.exposure);
		*ret_set = std::move(set);
	}
	if (ret_truth) {
		SimTruth t;
		t.head = std::move(surfaces[0].mesh);
		t.face = std::move(face);
		t.views = std::move(res.truth);
		t.projectors = projector_models(rig);
		t.projector_masks = projector_masks(rig);
		t.render_seconds = secs;
		*ret_truth = std::move(t);
	}
	return Status();
}

Status write_simulated_set(const std::string &dir, const CaptureSet &set, const SimTruth &truth)
{
	Status st = write_capture_set(dir, set);
	if (!st.ok())
		return st;
	st = write_ply(dir + "/ground_truth.ply", truth.head);
	if (!st.ok())
		return st;
	if (truth.face.size() == truth.head.vertices.size()) {
		// The face region as a mesh of its own (the truth's face vertices, the triangles among
		// them): the evaluation finds its vertices in ground_truth.ply by position, and anyone
		// can open it to see what "the face" is.
		Mesh face;
		std::vector<int> index(truth.face.size(), -1);
		for (size_t i = 0; i < truth.face.size(); i++)
			if (truth.face[i]) {
				index[i] = int(face.vertices.size());
				face.vertices.push_back(truth.head.vertices[i]);
				if (!truth.head.normals.empty())
					face.normals.push_back(truth.head.normals[i]);
			}
		for (const cv::Vec3i &t : truth.head.triangles)
			if (index[size_t(t[0])] >= 0 && index[size_t(t[1])] >= 0 && index[size_t(t[2])] >= 0)
				face.triangles.emplace_back(index[size_t(t[0])], index[size_t(t[1])], index[size_t(t[2])]);
		// A head with no face triangle (none drawn has one) gets no face file, and the dir no
		// stale one from an earlier render: evaluate then gives no face figures.
		if (face.triangles.empty()) {
			if (unlink((dir + "/ground_truth_face.ply").c_str()) < 0 && errno != ENOENT)
				return Status::error(-errno, dir + "/ground_truth_face.ply: cannot remove a stale face");
		} else {
			st = write_ply(dir + "/ground_truth_face.ply", face);
			if (!st.ok())
				return st;
		}
	}
	if (!truth.true_calibration.cameras.empty()) {
		st = write_calibration(dir + "/ground_truth_calibration.yaml", truth.true_calibration);
		if (!st.ok())
			return st;
	}
	Calibration projectors;
	projectors.cameras = truth.projectors;
	projectors.id = "simulated projectors";
	const std::string path = dir + "/ground_truth_projectors.yaml";
	st = write_calibration(path, projectors);
	bool masked = false;
	for (const auto &m : truth.projector_masks)
		masked |= !m.empty();
	if (!st.ok() || !masked)
		return st;
	// The masks go into the same file (one file says which points a projector lights):
	// calibration.yaml's format plus one key per masked projector, rewritten atomically.
	std::ifstream in(path, std::ios::binary);
	std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
	if (!in.good() && !in.eof())
		return Status::error(-EIO, path + ": cannot read back");
	if (!text.empty() && text.back() != '\n')
		text += '\n';
	for (size_t j = 0; j < truth.projector_masks.size(); j++) {
		if (truth.projector_masks[j].empty())
			continue;
		text += "cam" + std::to_string(j) + "_slide_mask: [";
		char buf[64];
		for (size_t k = 0; k < truth.projector_masks[j].size(); k++) {
			const cv::Point2d &q = truth.projector_masks[j][k];
			std::snprintf(buf, sizeof buf, "%s%.4f, %.4f", k ? ", " : " ", q.x, q.y);
			text += buf;
		}
		text += " ]\n";
	}
	return write_file_atomic(path, text.data(), text.size());
}

} // namespace facescan::sim

namespace facescan::sim {

cv::Mat contact_sheet(const CaptureSet &set, int tile_width)
{
	if (set.frames.empty() || tile_width < 16)
		return cv::Mat();
	const cv::Mat &f0 = set.frames[0];
	int th = int(std::lround(double(tile_width) * f0.rows / std::max(1, f0.cols)));
	std::vector<cv::Mat> rows;
	for (const std::vector<cv::Mat> *imgs : {&set.frames, &set.textures}) {
		if (imgs->empty())
			continue;
		std::vector<cv::Mat> tiles;
		for (size_t i = 0; i < imgs->size(); i++) {
			cv::Mat t;
			cv::resize((*imgs)[i], t, cv::Size(tile_width, th), 0, 0, cv::INTER_AREA);
			std::string label = "cam" + std::to_string(i) + (imgs == &set.textures ? " texture" : "");
			cv::putText(t, label, cv::Point(8, 22), cv::FONT_HERSHEY_SIMPLEX, 0.6,
				    cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
			tiles.push_back(t);
		}
		cv::Mat row;
		cv::hconcat(tiles, row);
		rows.push_back(row);
	}
	cv::Mat sheet;
	cv::vconcat(rows, sheet);
	return sheet;
}

} // namespace facescan::sim
