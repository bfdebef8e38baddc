#include "facescand/sim_booth.hpp"

#include "facescan/camera.h"
#include "sim/booth_camera.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>

namespace facescan::facescand {

namespace {

// A camera fault of one scan, from the sim_camera_faults file (docs/daemon.md, "Soak"): the
// sensor side of the simulated booth, so the driver and the daemon see it as they would a
// real camera's (a frame that never comes, or comes late).
struct CameraFault {
	int camera = -1; // -1: none
	bool drop = false;
	int delay_ms = 0;
};

// "drop CAMERA" or "delay CAMERA MS"; a missing or empty file is no fault. -EINVAL otherwise.
int read_camera_fault(const std::string &path, CameraFault *ret_fault)
{
	CameraFault f;
	if (path.empty()) {
		*ret_fault = f;
		return 0;
	}
	FILE *in = std::fopen(path.c_str(), "re");
	if (!in) {
		*ret_fault = f;
		return errno == ENOENT ? 0 : -errno;
	}
	char line[128] = "";
	bool have = std::fgets(line, sizeof(line), in) != nullptr;
	std::fclose(in);
	char word[16] = "";
	int camera = -1, ms = 0;
	int n = have ? std::sscanf(line, "%15s %d %d", word, &camera, &ms) : 0;
	if (n <= 0) {
		*ret_fault = f;
		return 0;
	}
	if (camera < 0 || camera >= 16)
		return -EINVAL;
	if (n == 2 && !std::strcmp(word, "drop"))
		f.drop = true;
	else if (n == 3 && !std::strcmp(word, "delay") && ms > 0 && ms <= 600000)
		f.delay_ms = ms;
	else
		return -EINVAL;
	f.camera = camera;
	*ret_fault = f;
	return 0;
}

class SimBooth : public daemon::SimulatedBooth {
public:
	SimBooth(fscan_sim_booth *booth, std::string faults_path) : booth_(booth), faults_path_(std::move(faults_path))
	{
	}
	~SimBooth() override
	{
		fscan_sim_booth_destroy(booth_);
	}
	SimBooth(const SimBooth &) = delete;
	SimBooth &operator=(const SimBooth &) = delete;

	Status camera_params(fscan_camera_params *ret_params) override
	{
		int rc = fscan_sim_booth_camera_params(booth_, ret_params);
		if (rc < 0)
			return Status::error(-rc, fscan_sim_booth_error(booth_));
		if (!faults_path_.empty()) {
			ret_params->render = render_with_faults;
			ret_params->render_user = this;
		}
		return Status();
	}
	Status write_last(const std::string &dir) override
	{
		int rc = fscan_sim_booth_write_last(booth_, dir.c_str());
		return rc < 0 ? Status::error(-rc, fscan_sim_booth_error(booth_)) : Status();
	}

private:
	fscan_sim_booth *booth_;
	std::string faults_path_;
	CameraFault fault_;

	// The booth's renderer, then this scan's fault on its camera (read at the scan's first frame).
	static int render_with_faults(void *user, uint32_t camera, uint32_t trigger_index, uint8_t *rgb,
				      uint32_t width, uint32_t height, uint32_t stride, uint64_t *ret_timestamp_ns)
	{
		auto *self = static_cast<SimBooth *>(user);
		if (camera == 0 && trigger_index == 0) {
			int rc = read_camera_fault(self->faults_path_, &self->fault_);
			if (rc < 0)
				return rc;
		}
		int rc = fscan_sim_booth_render(self->booth_, camera, trigger_index, rgb, width, height, stride,
						ret_timestamp_ns);
		if (rc < 0 || static_cast<int>(camera) != self->fault_.camera)
			return rc;
		return self->fault_.drop ? FSCAN_CAMERA_RENDER_DROPPED : self->fault_.delay_ms;
	}
};

} // namespace

Status make_sim_booth(const std::string &scene, double scale, const std::string &faults_path,
		      std::unique_ptr<daemon::SimulatedBooth> *ret_booth)
{
	fscan_sim_booth_params bp{};
	bp.scene = scene.c_str();
	bp.seed = 1;
	bp.scale = scale;
	fscan_sim_booth *booth = nullptr;
	int rc = fscan_sim_booth_create(&bp, &booth);
	if (rc < 0)
		return Status::error(-rc, std::strerror(-rc));
	std::unique_ptr<SimBooth> b(new (std::nothrow) SimBooth(booth, faults_path));
	if (!b) {
		fscan_sim_booth_destroy(booth);
		return Status::error(ENOMEM, std::strerror(ENOMEM));
	}
	*ret_booth = std::move(b);
	return Status();
}

} // namespace facescan::facescand
