#include "daemon/pipeline_recon.hpp"
#include "daemon/clock.hpp"

#include "capture/capture_set.hpp"
#include "eval/eval.hpp"
#include "mesh_io/mesh_io.hpp"
#include "pattern/pattern.hpp"
#include "recon/pipeline.hpp"

#include <opencv2/imgcodecs.hpp>


namespace facescan::daemon {

void add_simulated_accuracy(const std::string &dir, const recon::Mesh &mesh, const std::vector<CameraModel> &cameras,
			    ReconOutput *out)
{
	// A simulated set carries its ground truth (-ENOENT: a real capture, nothing to score).
	const auto t_eval = Clock::now();
	recon::Mesh truth;
	std::vector<CameraModel> lit_by;
	eval::EvalParams params; // the slide masks too, so the figures are `facescan evaluate`'s
	Status s = eval::read_ground_truth(dir, &truth, &lit_by, &params.projector_masks);
	if (s.code() == -ENOENT)
		return;
	eval::EvalResult e;
	if (s.ok())
		s = eval::evaluate(mesh, truth, cameras, lit_by, params, &e);
	if (s.ok())
		out->quality["accuracy"] = {{"rms_mm", e.rms_mm},
					    {"median_mm", e.median_mm},
					    {"p95_mm", e.p95_mm},
					    {"completeness", e.completeness},
					    {"against", "simulator ground truth"}};
	else
		out->quality["accuracy"] = {{"error", s.message()}};
	out->stage_ms.emplace_back("accuracy", ms_since(t_eval));
}

Status PipelineReconstructor::run(const Capture &capture, ReconOutput *ret_output)
{
	const auto t_read = Clock::now();
	CaptureSet set;
	Status s;
	if (!capture.source_dir.empty()) {
		s = read_capture_set(capture.source_dir, &set);
	} else {
		s = read_calibration(calibration_path_, &set.calibration);
		for (const Frame &f : capture.frames) {
			auto &v = f.texture ? set.textures : set.frames;
			if (v.size() <= static_cast<size_t>(f.camera))
				v.resize(static_cast<size_t>(f.camera) + 1);
			v[static_cast<size_t>(f.camera)] = f.image;
		}
		set.meta.pattern_id = pattern_id_;
	}
	if (!s.ok())
		return s;
	const double read_ms = ms_since(t_read);
	Pattern pattern;
	s = set.meta.pattern_id.empty() ? default_pattern(SlideSpec(), &pattern)
					: pattern_from_id(set.meta.pattern_id, SlideSpec(), &pattern);
	if (!s.ok())
		return s;
	recon::Mesh mesh;
	recon::ReconReport report;
	s = recon::reconstruct(set, pattern, recon::ReconParams(), &mesh, &report);
	if (!s.ok())
		return s;
	ReconOutput out;
	const auto t0 = Clock::now();
	std::vector<char> drc;
	s = mesh_io::encode_draco(mesh, mesh_io::DracoOptions(), &drc);
	if (!s.ok())
		return s;
	out.drc.assign(drc.begin(), drc.end());
	cv::Mat tex = mesh.texture;
	if (tex.empty() && !set.textures.empty())
		tex = set.textures[0];
	if (tex.empty() && !set.frames.empty())
		tex = set.frames[0];
	std::vector<uchar> png;
	if (!tex.empty() && !cv::imencode(".png", tex, png))
		return Status::error(EIO, "texture: PNG encoding failed");
	out.png.assign(png.begin(), png.end());
	const double encode_ms = ms_since(t0);
	// Where the daemon's reconstruct time goes: reading the set (a simulated booth leaves it on
	// disk), the pipeline's stages, encoding, and on simulated sets the accuracy check.
	out.stage_ms.emplace_back("read", read_ms);
	for (const recon::StageTime &st : report.stages)
		if (st.name != "total")
			out.stage_ms.emplace_back(st.name, st.ms);
	out.stage_ms.emplace_back("encode", encode_ms);
	out.vertices = static_cast<long>(mesh.positions.size());
	out.faces = static_cast<long>(mesh.triangles.size());
	out.quality = nlohmann::json::parse(recon::report_json(report), nullptr, false);
	if (out.quality.is_discarded())
		out.quality = nlohmann::json::object();
	if (!capture.source_dir.empty())
		add_simulated_accuracy(capture.source_dir, mesh, set.calibration.cameras, &out);
	*ret_output = std::move(out);
	return Status();
}

} // namespace facescan::daemon
