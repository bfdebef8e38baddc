#include "facescand/sim_booth.hpp"

#include "facescan/camera.h"
#include "sim/booth_camera.h"

#include <cerrno>
#include <cstring>
#include <new>

namespace facescan::facescand {

namespace {

class SimBooth : public daemon::SimulatedBooth {
public:
	explicit SimBooth(fscan_sim_booth *booth) : booth_(booth)
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
		return rc < 0 ? Status::error(-rc, fscan_sim_booth_error(booth_)) : Status();
	}
	Status write_last(const std::string &dir) override
	{
		int rc = fscan_sim_booth_write_last(booth_, dir.c_str());
		return rc < 0 ? Status::error(-rc, fscan_sim_booth_error(booth_)) : Status();
	}

private:
	fscan_sim_booth *booth_;
};

} // namespace

Status make_sim_booth(const std::string &scene, double scale, std::unique_ptr<daemon::SimulatedBooth> *ret_booth)
{
	fscan_sim_booth_params bp{};
	bp.scene = scene.c_str();
	bp.seed = 1;
	bp.scale = scale;
	fscan_sim_booth *booth = nullptr;
	int rc = fscan_sim_booth_create(&bp, &booth);
	if (rc < 0)
		return Status::error(-rc, std::strerror(-rc));
	std::unique_ptr<SimBooth> b(new (std::nothrow) SimBooth(booth));
	if (!b) {
		fscan_sim_booth_destroy(booth);
		return Status::error(ENOMEM, std::strerror(ENOMEM));
	}
	*ret_booth = std::move(b);
	return Status();
}

} // namespace facescan::facescand
