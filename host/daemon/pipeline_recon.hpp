// The reconstruction library (host/recon) as the daemon's Reconstructor. Its input is the
// capture set the cameras left on disk (Capture::source_dir: replay, simulated), or the frames
// in memory with the booth's calibration file and pattern (libcamera). It runs
// recon::reconstruct(), encodes Draco and the texture, and where the set is simulated
// (ground_truth.ply beside it) measures the accuracy with host/eval.
#pragma once

#include "capture/capture_set.hpp"
#include "daemon/backends.hpp"
#include "recon/types.hpp"

namespace facescan::daemon {

class PipelineReconstructor : public Reconstructor {
public:
	/// calibration_path: calibration.yaml for frames that come without one; pattern_id: the
	/// booth's slide ("" = this build's default pattern).
	PipelineReconstructor(std::string calibration_path, std::string pattern_id)
		: calibration_path_(std::move(calibration_path)), pattern_id_(std::move(pattern_id))
	{
	}
	std::string backend_name() const override
	{
		return "pipeline";
	}
	Status run(const Capture &capture, ReconOutput *ret_output) override;

private:
	std::string calibration_path_, pattern_id_;
};

/// Where `dir` is a simulated set (its ground truth beside it), scores `mesh` against it as
/// `facescan evaluate` does and adds quality["accuracy"] and an "accuracy" stage time to `out`.
void add_simulated_accuracy(const std::string &dir, const recon::Mesh &mesh, const std::vector<CameraModel> &cameras,
			    ReconOutput *out);

} // namespace facescan::daemon
