// The reconstruction pipeline. See pipeline.hpp.
#include "recon/pipeline.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>

namespace facescan::recon {

namespace {

class Timer {
public:
	explicit Timer(std::vector<StageTime> *out) : out_(out), start_(now()), first_(start_) {}
	void lap(const char *name)
	{
		const double t = now();
		out_->push_back({name, (t - start_) * 1e3});
		start_ = t;
	}
	void total() { out_->push_back({"total", (now() - first_) * 1e3}); }

private:
	static double now()
	{
		return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
	}
	std::vector<StageTime> *out_;
	double start_, first_;
};

Status check_input(const CaptureSet &set, const ReconParams &params)
{
	const size_t n = set.calibration.cameras.size();
	if (n < 2)
		return Status::error(-EINVAL, "calibration has " + std::to_string(n) +
						      " camera(s); reconstruction needs at least 2");
	if (set.frames.size() != n)
		return Status::error(-EINVAL, "capture set has " + std::to_string(set.frames.size()) +
						      " frames for " + std::to_string(n) + " calibrated cameras");
	if (!set.textures.empty() && set.textures.size() != n)
		return Status::error(-EINVAL, "capture set has " + std::to_string(set.textures.size()) +
						      " texture frames for " + std::to_string(n) + " cameras");
	for (size_t c = 0; c < n; ++c) {
		const cv::Mat &f = set.frames[c];
		const CameraModel &cam = set.calibration.cameras[c];
		const std::string who = "camera " + std::to_string(c);
		if (f.empty() || f.type() != CV_8UC3)
			return Status::error(-EINVAL, who + ": frame is empty or not 8-bit 3-channel");
		if (f.size() != cam.size)
			return Status::error(-EINVAL, who + ": frame is " + std::to_string(f.cols) + "x" +
							      std::to_string(f.rows) + " but the calibration says " +
							      std::to_string(cam.size.width) + "x" +
							      std::to_string(cam.size.height));
		if (!set.textures.empty() && set.textures[c].size() != cam.size)
			return Status::error(-EINVAL, who + ": texture frame size differs from the calibration");
		cv::Scalar mean, stddev;
		cv::meanStdDev(f, mean, stddev);
		const double sd = std::max({stddev[0], stddev[1], stddev[2]});
		if (sd < params.min_frame_stddev) {
			const double m = (mean[0] + mean[1] + mean[2]) / 3;
			const char *what = m > 200 ? "all white" : m < 55 ? "all black" : "uniform";
			return Status::error(-EINVAL, who + ": frame is " + what + " (mean " +
							      std::to_string(int(m)) + ", std dev " +
							      cv::format("%.2f", sd) + "): no pattern to decode");
		}
	}
	return {};
}

} // namespace

Status reconstruct(const CaptureSet &set, const Pattern &pattern, const ReconParams &params, Mesh *ret_mesh,
		   ReconReport *ret_report, ReconDebug *ret_debug)
{
	ReconReport report;
	report.scan_id = set.meta.scan_id;
	report.pattern_id = pattern.id;
	Timer timer(&report.stages);
	Status s = check_input(set, params);
	if (!s.ok())
		return s;
	// The calibration as written; stage 6a may refine its extrinsics on this scan's own matches.
	std::vector<CameraModel> cams = set.calibration.cameras;
	const size_t n = cams.size();

	// Stages 1-3 and 5, one camera per task.
	std::vector<CameraDetections> dets(n);
	std::vector<Status> det_status(n);
	cv::parallel_for_(cv::Range(0, int(n)), [&](const cv::Range &r) {
		for (int c = r.start; c < r.end; ++c) {
			dets[size_t(c)].camera = c;
			det_status[size_t(c)] = detect_squares(set.frames[size_t(c)], pattern, params.detect,
							       &dets[size_t(c)]);
		}
	});
	if (ret_debug)
		for (size_t c = 0; c < n; ++c)
			if (det_status[c].ok())
				ret_debug->images.push_back({"cam" + std::to_string(c) + "_squares",
							     draw_detections(set.frames[c], dets[c])});
	for (size_t c = 0; c < n; ++c) {
		if (!det_status[c].ok())
			return Status::error(det_status[c].code(),
					     "camera " + std::to_string(c) + ": " + det_status[c].message());
		CameraReport cr;
		cr.camera = int(c);
		cr.detected = dets[c].detected;
		cr.decoded = dets[c].decoded;
		cr.corrected = dets[c].corrected;
		cr.rejected = dets[c].rejected;
		for (const Square &sq : dets[c].squares)
			cr.with_corners += sq.has_corners;
		report.cameras.push_back(cr);
	}
	// A camera whose code is unreadable (a slide it sees too small or too rolled, a lens out of
	// focus, two projectors' grids overlapping on the face) still has the pattern's texture: its
	// pairs get no seeds, and the dense stage searches them over the working volume. That holds
	// even when no pair has the code in both views, as long as some camera reads it (so the
	// pattern is there and is the one capture.json names): random booth 1606 with the scanned
	// head (cameras 1 and 3 decode nothing under overlapping grids) failed here, and the dense
	// search alone gives RMS 0.32 mm, completeness 72.6 %. Without any camera reading the code,
	// or for the paper's mesh alone (--sparse), which is made of code matches, there is nothing
	// to reconstruct.
	const auto patterned = [&](size_t c) { return report.cameras[c].decoded >= params.min_decoded_squares; };
	bool anchored = false, any_code = false;
	for (size_t c = 0; c < n; ++c) {
		any_code = any_code || patterned(c);
		anchored = anchored || (c + 1 < n && patterned(c) && patterned(c + 1));
	}
	if (!any_code || (!anchored && !params.dense_enabled)) {
		// Every camera's count: which view lost the code is what the user needs to see.
		std::string counts;
		for (size_t c = 0; c < n; ++c)
			counts += (c ? ", " : "") + std::to_string(c) + ": " + std::to_string(report.cameras[c].decoded) +
				  " of " + std::to_string(report.cameras[c].detected);
		for (size_t c = 0; c < n; ++c)
			if (!patterned(c))
				return Status::error(-ENODATA, "camera " + std::to_string(c) + ": no pattern found (" +
								       (any_code ? "no pair has the code in both views"
										 : "no camera reads the code") +
								       "; decoded squares per camera " + counts +
								       ", need " +
								       std::to_string(params.min_decoded_squares) + ")");
	}
	timer.lap("detect");

	// Stage 4, consecutive pairs.
	std::vector<PairMatches> matches(n - 1);
	for (size_t p = 0; p + 1 < n; ++p) {
		s = match_pair(dets[p], dets[p + 1], cams[p], cams[p + 1], pattern, params.match, &matches[p]);
		if (!s.ok())
			return Status::error(s.code(), "pair " + std::to_string(p) + "-" + std::to_string(p + 1) +
							       ": " + s.message());
		matches[p].cam_a = int(p);
		matches[p].cam_b = int(p + 1);
		if (ret_debug)
			ret_debug->images.push_back({"pair" + std::to_string(p) + "_matches",
						     draw_matches(set.frames[p], set.frames[p + 1], matches[p])});
		PairReport pr;
		pr.cam_a = int(p);
		pr.cam_b = int(p + 1);
		pr.matches = int(matches[p].matches.size());
		for (const PointMatch &m : matches[p].matches)
			(m.feature == kCentroid ? pr.centroid_matches : pr.corner_matches)++;
		pr.rejected_epipolar = matches[p].rejected_epipolar;
		pr.rejected_ambiguous = matches[p].rejected_ambiguous;
		pr.grown = matches[p].grown;
		pr.guided = matches[p].guided;
		pr.seeded = matches[p].seeded;
		pr.pruned = matches[p].pruned;
		report.pairs.push_back(pr);
	}
	// The paper's multiplier measures the corner detector: over the squares matched by their code
	// word (the paper's set). Grown squares are mostly the ones without usable corners, so the
	// ratio over all matches is reported beside it.
	int all = 0, centroids = 0, coded = 0, coded_centroids = 0;
	for (const PairMatches &pm : matches)
		for (const PointMatch &m : pm.matches) {
			all++;
			centroids += m.feature == kCentroid;
			coded += !m.grown;
			coded_centroids += !m.grown && m.feature == kCentroid;
		}
	report.corner_multiplier = coded_centroids ? double(coded) / coded_centroids : 0;
	report.points_per_square = centroids ? double(all) / centroids : 0;
	timer.lap("match");

	// Stage 6a.
	s = refine_extrinsics(matches, {}, params.bundle, &cams, &report.bundle);
	if (!s.ok())
		return s;
	timer.lap("bundle");

	// Stage 6.
	std::vector<PartialModel> models(n - 1);
	for (size_t p = 0; p + 1 < n; ++p) {
		s = triangulate_pair(matches[p], cams[p], cams[p + 1], params.triangulate, &models[p],
				     &report.pairs[p].triangulate);
		if (!s.ok())
			return s;
	}
	timer.lap("triangulate");

	// Stage 7.
	for (size_t p = 0; p + 1 < n; ++p) {
		s = mesh_partial(cams[p], cams[p + 1], params.meshing, &models[p], &report.pairs[p].meshing);
		if (!s.ok())
			return s;
	}
	timer.lap("mesh");

	// Stage 8.
	s = register_models(&models, params.registration, &report.registration);
	if (!s.ok())
		return s;
	timer.lap("register");

	// Stage 9.
	Mesh mesh;
	// With too few code matches for the paper's mesh the dense stage may still carry the scan
	// (its unseeded search); the sparse error stands if it cannot.
	const Status sparse_status = fuse_models(models, cams, params.fusion, &mesh, &report.fusion);
	if (!sparse_status.ok() && !(sparse_status.code() == -ENODATA && params.dense_enabled))
		return sparse_status;
	timer.lap("fuse");

	report.sparse_vertices = int(mesh.positions.size());
	report.sparse_triangles = int(mesh.triangles.size());

	// Dense: per pair, seeded by its sparse model, moved by the pair's registration, fused.
	if (params.dense_enabled) {
		std::vector<DenseCloud> clouds(n - 1);
		std::vector<DensePairDebug> dbg(n - 1);
		std::vector<Status> pair_status(n - 1);
		std::vector<PreparedPair> prepared(n - 1);
		// The pairs are independent, and much of a pair's time is single-threaded (the prior,
		// the refinement, the flat refill, the filters): they run concurrently so that no core
		// idles while one pair is in such a part.
		cv::parallel_for_(cv::Range(0, int(n - 1)), [&](const cv::Range &r) {
			for (int i = r.start; i < r.end; ++i) {
				const size_t p = size_t(i);
				pair_status[p] = prepare_pair(set.frames[p], set.frames[p + 1], cams[p], cams[p + 1],
							      models[p], params.dense, &prepared[p]);
				if (pair_status[p].ok())
					pair_status[p] = match_pair(prepared[p], nullptr, &clouds[p],
								    &report.pairs[p].dense, ret_debug ? &dbg[p] : nullptr);
			}
		});
		// Each pair again, its prior filled where the code's small triangles give none by every
		// pair's points (its own too) instead of the coarse search: a pair that reads another
		// copy of the slide than its neighbours, or none, is guided by theirs; a pair whose coarse
		// search strayed, by what it and they matched around the stray patch (the code's small
		// triangles cover a quarter of a pair's lit pixels, median of 144 bench pairs). A pair
		// whose second match fails keeps its first.
		if (params.dense.guided_pass) {
			std::vector<cv::Point3f> guide;
			for (size_t p = 0; p + 1 < n; ++p)
				if (pair_status[p].ok())
					guide.insert(guide.end(), clouds[p].points.begin(), clouds[p].points.end());
			cv::parallel_for_(cv::Range(0, int(n - 1)), [&](const cv::Range &r) {
				for (int i = r.start; i < r.end; ++i) {
					const size_t p = size_t(i);
					if (!pair_status[p].ok() || guide.empty())
						continue;
					DenseCloud cloud;
					DenseStats stats;
					DensePairDebug d;
					DensePairDebug *debug = ret_debug ? &d : nullptr;
					if (match_pair(prepared[p], &guide, &cloud, &stats, debug).ok()) {
						clouds[p] = std::move(cloud);
						report.pairs[p].dense = stats;
						dbg[p] = std::move(d);
					}
				}
			});
		}
		prepared.clear();
		for (size_t p = 0; p + 1 < n; ++p) {
			s = pair_status[p];
			if (ret_debug && s.ok() && !dbg[p].left.empty()) {
				const std::string name = "pair" + std::to_string(p);
				double lo = 0, hi = 0;
				cv::Mat finite = has_value(dbg[p].prior);
				if (cv::countNonZero(finite) > 0)
					cv::minMaxLoc(dbg[p].prior, &lo, &hi, nullptr, nullptr, finite);
				cv::Mat overlay;
				cv::addWeighted(dbg[p].left, 0.5, dbg[p].warped, 0.5, 0, overlay);
				ret_debug->images.push_back({name + "_rectified_left", dbg[p].left});
				ret_debug->images.push_back({name + "_warped_right", dbg[p].warped});
				ret_debug->images.push_back({name + "_left_over_warped", overlay});
				ret_debug->images.push_back({name + "_prior", colour_map(dbg[p].prior, lo, hi)});
				ret_debug->images.push_back({name + "_disparity", colour_map(dbg[p].disparity, lo, hi)});
				// Raw DenseReason codes (1-12), not for the eye: `facescan evaluate --missing`.
				ret_debug->images.push_back({name + "_reasons", dbg[p].reason});
				cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
				fs << "cam_a" << int(p) << "cam_b" << int(p + 1) << "world_to_left"
				   << cv::Mat(dbg[p].world_to_left);
				ret_debug->texts.push_back({name + "_rectification.yaml", fs.releaseAndGetString()});
			}
			// One pair's failure costs its view, not the scan: the other pairs' clouds still
			// make a surface (the report says which pair is missing and why).
			if (!s.ok()) {
				report.pairs[p].dense_error = s.message();
				report.pairs[p].dense.points = 0;
				clouds[p] = DenseCloud{};
			}
		}
		timer.lap("dense");
		// Stage 6b: stage 6a again, from the calibration as written, with the dense clouds chained
		// through the shared cameras: three-view tracks tie each pair's depth to its
		// neighbours', which the code's mostly two-view tracks cannot (held-out booth 3007:
		// RMS 0.316 -> 0.263 mm, 0.270 with the true calibration). The clouds are
		// re-triangulated with the refined cameras, which the surface and the texture then use.
		if (params.bundle.enabled && params.bundle.chain_cell_px > 0) {
			std::vector<Track> tracks;
			chain_dense_tracks(clouds, cams, params.bundle, &tracks);
			// Without chained tracks the refinement would be stage 6a's again, to the same cameras.
			if (!tracks.empty()) {
				std::vector<CameraModel> refined = set.calibration.cameras;
				s = refine_extrinsics(matches, tracks, params.bundle, &refined, &report.bundle_dense);
				if (!s.ok())
					return s;
				if (report.bundle_dense.applied) {
					retriangulate_clouds(cams, refined, &clouds);
					cams = refined;
				}
			}
		}
		timer.lap("bundle_dense");
		{
			std::vector<std::vector<cv::Point3f>> points(clouds.size());
			for (size_t p = 0; p < clouds.size(); ++p)
				points[p] = std::move(clouds[p].points);
			s = register_dense(&points, params.registration, &report.registration);
			for (size_t p = 0; p < clouds.size(); ++p)
				clouds[p].points = std::move(points[p]);
			if (!s.ok())
				return s;
		}
		// The clouds as the surface gets them (moved by the registration).
		if (ret_debug)
			for (size_t p = 0; p < clouds.size(); ++p)
				if (!clouds[p].points.empty())
					ret_debug->clouds.push_back({"pair" + std::to_string(p) + "_dense", clouds[p].points,
								     clouds[p].confidence});
		timer.lap("register_dense");
		Mesh dense;
		s = fuse_dense(clouds, mesh.positions, cams, params.surface, &dense, &report.surface);
		if (s.ok()) {
			mesh = std::move(dense);
			report.dense = true;
		} else if (s.code() != -ENODATA) {
			return s;
		}
		timer.lap("fuse_dense");
	}
	if (!sparse_status.ok() && !report.dense)
		return sparse_status;

	// Stage 10.
	if (params.texture_enabled) {
		s = texture_mesh(set.textures, set.frames, cams, params.texture, &mesh, &report.texture);
		if (!s.ok())
			return s;
	}
	timer.lap("texture");
	timer.total();
	report.vertices = int(mesh.positions.size());
	report.triangles = int(mesh.triangles.size());
	*ret_mesh = std::move(mesh);
	if (ret_report)
		*ret_report = std::move(report);
	return {};
}

std::string report_json(const ReconReport &r)
{
	using nlohmann::json;
	json j;
	j["scan_id"] = r.scan_id;
	j["pattern"] = r.pattern_id;
	json times = json::object();
	for (const StageTime &t : r.stages)
		times[t.name] = t.ms;
	j["time_ms"] = times;
	json cams = json::array();
	for (const CameraReport &c : r.cameras)
		cams.push_back({{"camera", c.camera}, {"detected", c.detected}, {"decoded", c.decoded},
				{"corrected", c.corrected}, {"rejected", c.rejected}, {"with_corners", c.with_corners}});
	j["cameras"] = cams;
	json pairs = json::array();
	for (const PairReport &p : r.pairs)
		pairs.push_back({{"cameras", {p.cam_a, p.cam_b}},
				 {"matches", p.matches},
				 {"centroid_matches", p.centroid_matches},
				 {"corner_matches", p.corner_matches},
				 {"rejected_epipolar", p.rejected_epipolar},
				 {"rejected_ambiguous", p.rejected_ambiguous},
				 {"grown", p.grown},
				 {"guided", p.guided},
				 {"seeded", p.seeded},
				 {"pruned", p.pruned},
				 {"triangulated", p.triangulate.kept},
				 {"dropped_reprojection", p.triangulate.dropped_reprojection},
				 {"dropped_depth", p.triangulate.dropped_depth},
				 {"mean_reprojection_px", p.triangulate.mean_reprojection_px},
				 {"triangles", p.meshing.kept},
				 {"triangles_dropped_long", p.meshing.dropped_long},
				 {"triangles_dropped_grazing", p.meshing.dropped_grazing},
				 {"median_edge_mm", p.meshing.median_edge_mm},
				 {"dense",
				  {{"seeds", p.dense.seeds},
				   {"prior_pixels", p.dense.prior_pixels},
				   {"matched", p.dense.matched},
				   {"coarse_pixels", p.dense.coarse_pixels},
				   {"unlit", p.dense.unlit},
				   {"low_confidence", p.dense.low_confidence},
				   {"near_unmatched", p.dense.near_unmatched},
				   {"flat_filled", p.dense.flat_filled},
				   {"flat_kept", p.dense.flat_kept},
				   {"flat_dropped", p.dense.flat_dropped},
				   {"flat_unfitted_dropped", p.dense.flat_unfitted_dropped},
				   {"dark_bridged", p.dense.dark_bridged},
				   {"seed_cover", p.dense.seed_cover},
				   {"coarse_over_volume", p.dense.coarse_over_volume},
				   {"guided_pixels", p.dense.guided_pixels},
				   {"at_search_edge", p.dense.at_search_edge},
				   {"steep", p.dense.steep},
				   {"rim", p.dense.rim},
				   {"islands", p.dense.islands},
				   {"points", p.dense.points},
				   {"median_seed_spacing_px", p.dense.median_spacing_px},
				   {"error", p.dense_error}}}});
	j["pairs"] = pairs;
	{
		for (const auto &[key, b] : {std::pair<const char *, const BundleStats &>{"bundle", r.bundle},
					     std::pair<const char *, const BundleStats &>{"bundle_dense", r.bundle_dense}}) {
			json moved = json::array();
			for (const BundleCamera &c : b.cameras)
				moved.push_back(
					{{"camera", c.camera}, {"rotation_mrad", c.rotation_mrad}, {"centre_mm", c.centre_mm}});
			j[key] = {{"applied", b.applied},
				  {"tracks", b.tracks},
				  {"tracks_3_views", b.tracks_3_views},
				  {"extra_tracks", b.extra_tracks},
				  {"observations", b.observations},
				  {"rms_before_px", b.rms_before_px},
				  {"rms_after_px", b.rms_after_px},
				  {"cameras", moved}};
		}
	}
	json reg = json::array();
	for (const RegistrationPair &p : r.registration)
		reg.push_back({{"model", p.model}, {"onto", p.onto}, {"shared", p.shared}, {"inliers", p.inliers},
			       {"D_before_mm2", p.d_before}, {"D_after_mm2", p.d_after},
			       {"D_before_all_mm2", p.d_before_all}, {"D_after_all_mm2", p.d_after_all},
			       {"applied", p.applied},
			       {"dense_before_mm", p.dense_before_mm}, {"dense_after_mm", p.dense_after_mm},
			       {"applied_dense", p.applied_dense},
			       {"T_mm", {p.T[0], p.T[1], p.T[2]}}});
	j["registration"] = reg;
	j["fusion"] = {{"input_points", r.fusion.input_points}, {"vertices", r.fusion.vertices},
		       {"merged", r.fusion.merged}, {"squares", r.fusion.squares}, {"triangles", r.fusion.triangles},
		       {"median_edge_mm", r.fusion.meshing.median_edge_mm}};
	j["dense"] = r.dense;
	j["sparse"] = {{"vertices", r.sparse_vertices}, {"triangles", r.sparse_triangles}};
	j["surface"] = {{"input_points", r.surface.input_points}, {"cells", r.surface.cells},
			{"merged", r.surface.merged}, {"vertices", r.surface.vertices},
			{"outliers", r.surface.outliers}, {"trimmed", r.surface.trimmed},
			{"piece_triangles_dropped", r.surface.piece_triangles_dropped},
			{"piece_triangles_two_pairs", r.surface.piece_triangles_two_pairs},
			{"piece_triangles_code", r.surface.piece_triangles_code},
			{"triangles", r.surface.triangles}, {"spacing_mm", r.surface.spacing_mm}};
	j["texture"] = {{"charts", r.texture.charts},
			{"untextured_triangles", r.texture.untextured},
			{"vertex_colours", r.texture.vertex_colours},
			{"atlas", {r.texture.atlas.width, r.texture.atlas.height}}};
	j["corner_multiplier"] = r.corner_multiplier;
	j["points_per_square"] = r.points_per_square;
	j["vertices"] = r.vertices;
	j["triangles"] = r.triangles;
	if (r.peak_rss_kb > 0)
		j["peak_rss_kb"] = r.peak_rss_kb;
	return j.dump(2) + "\n";
}

} // namespace facescan::recon
