// The booth simulator as the simulated camera backend's render callback (booth_camera.h).
// Here, not in drivers/camera: the driver takes the callback and knows no simulator (layers).
#include "sim/booth_camera.h"

#include "capture/capture_set.hpp"
#include "pattern/pattern.hpp"
#include "sim/sim.hpp"

#include <opencv2/imgproc.hpp>

#include <cerrno>
#include <cstring>
#include <new>
#include <string>

struct fscan_sim_booth {
	facescan::sim::Rig rig;
	facescan::sim::Scene scene;
	facescan::Pattern pattern;
	uint64_t seed = 0;
	uint64_t scans = 0;
	bool have_scan = false;
	facescan::CaptureSet set;
	facescan::sim::SimTruth truth;
	std::string error;
};

namespace {

int fail(fscan_sim_booth *b, const facescan::Status &st)
{
	b->error = st.message();
	return st.code() ? st.code() : -EIO;
}

} // namespace

extern "C" int fscan_sim_booth_create(const struct fscan_sim_booth_params *params, struct fscan_sim_booth **ret_booth)
{
	if (!params || !ret_booth)
		return -EINVAL;
	if (params->scale < 0 || params->scale > 4)
		return -EINVAL;
	try {
		auto *b = new fscan_sim_booth;
		facescan::Status st;
		if (params->rig_path)
			st = facescan::sim::load_rig(params->rig_path, &b->rig);
		else
			b->rig = facescan::sim::default_rig();
		if (st.ok() && params->scale > 0 && params->scale != 1.0)
			st = facescan::sim::scale_rig(params->scale, &b->rig);
		if (st.ok())
			st = facescan::sim::scene_by_name(params->scene ? params->scene : "default", &b->scene);
		if (st.ok()) {
			facescan::SlideSpec slide;
			if (!b->rig.projectors.empty()) {
				slide.width = b->rig.projectors[0].size.width;
				slide.height = b->rig.projectors[0].size.height;
			}
			st = params->pattern_id ? facescan::pattern_from_id(params->pattern_id, slide, &b->pattern)
						: facescan::default_pattern(slide, &b->pattern);
		}
		if (st.ok() && b->rig.cameras.empty())
			st = facescan::Status::error(-EINVAL, "the rig has no camera");
		if (!st.ok()) {
			int r = st.code();
			delete b;
			return r;
		}
		b->seed = params->seed;
		*ret_booth = b;
		return 0;
	} catch (const std::bad_alloc &) {
		return -ENOMEM;
	}
}

extern "C" void fscan_sim_booth_destroy(struct fscan_sim_booth *booth)
{
	delete booth;
}

extern "C" int fscan_sim_booth_geometry(const struct fscan_sim_booth *booth, uint32_t *ret_count, uint32_t *ret_width,
					uint32_t *ret_height)
{
	if (!booth || !ret_count || !ret_width || !ret_height)
		return -EINVAL;
	const cv::Size size = booth->rig.cameras[0].model.size;
	for (const auto &c : booth->rig.cameras)
		if (c.model.size != size)
			return -EINVAL;
	*ret_count = (uint32_t)booth->rig.cameras.size();
	*ret_width = (uint32_t)size.width;
	*ret_height = (uint32_t)size.height;
	return 0;
}

extern "C" int fscan_sim_booth_camera_params(struct fscan_sim_booth *booth, struct fscan_camera_params *ret_params)
{
	if (!booth || !ret_params)
		return -EINVAL;
	struct fscan_camera_params p;
	std::memset(&p, 0, sizeof(p));
	int r = fscan_sim_booth_geometry(booth, &p.count, &p.width, &p.height);
	if (r < 0)
		return r;
	p.render = fscan_sim_booth_render;
	p.render_user = booth;
	*ret_params = p;
	return 0;
}

extern "C" int fscan_sim_booth_render(void *user, uint32_t camera, uint32_t trigger_index, uint8_t *rgb, uint32_t width,
				      uint32_t height, uint32_t stride, uint64_t *ret_timestamp_ns)
{
	auto *b = static_cast<fscan_sim_booth *>(user);
	if (!b || !rgb || trigger_index > 1 || camera >= b->rig.cameras.size())
		return -EINVAL;
	(void)ret_timestamp_ns; // the backend's synthetic time: one flash, cameras 10 us apart
	try {
		if (camera == 0 && trigger_index == 0) {
			b->have_scan = false;
			b->error.clear();
			facescan::sim::SimOptions options;
			options.texture_frames = true;
			facescan::Status st = facescan::sim::simulate(b->rig, b->scene, b->pattern, b->seed + b->scans++,
								      &b->set, &b->truth, options);
			if (!st.ok())
				return fail(b, st);
			b->have_scan = true;
		}
		if (!b->have_scan)
			return -ENODATA;
		const std::vector<cv::Mat> &images = trigger_index == 0 ? b->set.frames : b->set.textures;
		if (camera >= images.size())
			return -ENODATA;
		const cv::Mat &bgr = images[camera];
		if ((uint32_t)bgr.cols != width || (uint32_t)bgr.rows != height || bgr.type() != CV_8UC3)
			return -EINVAL;
		cv::Mat out((int)height, (int)width, CV_8UC3, rgb, stride);
		cv::cvtColor(bgr, out, cv::COLOR_BGR2RGB);
		return 0;
	} catch (const std::bad_alloc &) {
		return -ENOMEM;
	} catch (const cv::Exception &e) {
		b->error = e.what();
		return -EIO;
	}
}

extern "C" int fscan_sim_booth_write_last(const struct fscan_sim_booth *booth, const char *dir)
{
	if (!booth || !dir)
		return -EINVAL;
	if (!booth->have_scan)
		return -ENODATA;
	try {
		facescan::Status st = facescan::sim::write_simulated_set(dir, booth->set, booth->truth);
		if (!st.ok()) {
			const_cast<fscan_sim_booth *>(booth)->error = st.message();
			return st.code();
		}
		return 0;
	} catch (const std::bad_alloc &) {
		return -ENOMEM;
	}
}

extern "C" const char *fscan_sim_booth_error(const struct fscan_sim_booth *booth)
{
	return booth ? booth->error.c_str() : "";
}
