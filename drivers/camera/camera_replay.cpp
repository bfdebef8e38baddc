// Replay camera backend: serves a saved capture set (docs/capture-format.md) as if its cameras
// had just been triggered. Trigger 0 of an arm gets cam{i}.png, trigger 1 cam{i}_texture.png.
// Reading goes through host/capture (the format's one reader), so the checks are the same as
// recon's. C++ behind the C ops table; nothing throws across it.
#include "camera_internal.h"

#include "capture/capture_set.hpp"

#include <opencv2/imgproc.hpp>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <new>
#include <time.h>

namespace {

struct Replay {
	facescan::CaptureSet set;
	std::deque<fscan_camera_raw_frame> ready;
	uint64_t epoch_ns = 0;
};

uint64_t mono_ns()
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

void clear_ready(Replay *r)
{
	for (auto &f : r->ready)
		std::free(f.frame.data);
	r->ready.clear();
}

int replay_open(const struct fscan_camera_params *p, void **ret_ctx)
{
	if (!p->source || !*p->source)
		return -EINVAL;
	Replay *r = new (std::nothrow) Replay;
	if (!r)
		return -ENOMEM;
	try {
		facescan::Status st = facescan::read_capture_set(p->source, &r->set);
		if (!st.ok()) {
			int code = st.code();
			delete r;
			return code == -ENOENT ? -ENOENT : code == -ENOMEM ? -ENOMEM : -EBADMSG;
		}
	} catch (const std::bad_alloc &) {
		delete r;
		return -ENOMEM;
	} catch (...) {
		delete r;
		return -EBADMSG;
	}
	r->epoch_ns = mono_ns();
	*ret_ctx = r;
	return 0;
}

void replay_close(void *ctx)
{
	Replay *r = static_cast<Replay *>(ctx);
	clear_ready(r);
	delete r;
}

int replay_count(void *ctx)
{
	return (int)static_cast<Replay *>(ctx)->set.frames.size();
}

int replay_info(void *ctx, uint32_t camera, struct fscan_camera_info *ret)
{
	Replay *r = static_cast<Replay *>(ctx);
	std::memset(ret, 0, sizeof(*ret));
	std::snprintf(ret->id, sizeof(ret->id), "replay:cam%u", camera);
	std::snprintf(ret->model, sizeof(ret->model), "replay");
	ret->width = (uint32_t)r->set.frames[camera].cols;
	ret->height = (uint32_t)r->set.frames[camera].rows;
	return 0;
}

int replay_configure(void *ctx, const struct fscan_camera_config *cfg)
{
	Replay *r = static_cast<Replay *>(ctx);
	// A recording has the size it has: accept it or "sensor size" (0).
	for (const cv::Mat &m : r->set.frames)
		if ((cfg->width && cfg->width != (uint32_t)m.cols) || (cfg->height && cfg->height != (uint32_t)m.rows))
			return -EINVAL;
	return 0;
}

int replay_arm(void *ctx, uint32_t first_seq, uint32_t n)
{
	Replay *r = static_cast<Replay *>(ctx);
	uint32_t shots = r->set.textures.empty() ? 1 : 2;
	if (n > shots)
		return -ENODATA;
	clear_ready(r);
	const auto &ts = r->set.meta.timestamps_ns;
	try {
		for (uint32_t t = 0; t < n; t++) {
			uint32_t seq = first_seq + t;
			const std::vector<cv::Mat> &images = t == 0 ? r->set.frames : r->set.textures;
			for (uint32_t c = 0; c < images.size(); c++) {
				fscan_camera_raw_frame f;
				std::memset(&f, 0, sizeof(f));
				const cv::Mat &bgr = images[c];
				f.frame.camera = c;
				f.frame.trigger_seq = seq;
				f.frame.width = (uint32_t)bgr.cols;
				f.frame.height = (uint32_t)bgr.rows;
				f.frame.stride = (uint32_t)bgr.cols * 3u;
				// Recorded sensor times when the set has them; the texture shot 100 ms on.
				uint64_t base = ts.size() == images.size() ? (uint64_t)ts[c]
									  : r->epoch_ns + (uint64_t)seq * 100000000u + c * 10000u;
				f.frame.timestamp_ns = base + (ts.size() == images.size() ? (uint64_t)t * 100000000u : 0);
				f.frame.data = static_cast<uint8_t *>(std::malloc((size_t)f.frame.stride * f.frame.height));
				if (!f.frame.data) {
					clear_ready(r);
					return -ENOMEM;
				}
				cv::Mat rgb((int)f.frame.height, (int)f.frame.width, CV_8UC3, f.frame.data, f.frame.stride);
				cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
				r->ready.push_back(f);
			}
		}
	} catch (...) {
		clear_ready(r);
		return -ENOMEM;
	}
	return 0;
}

int replay_next_frame(void *ctx, int timeout_ms, struct fscan_camera_raw_frame *ret)
{
	Replay *r = static_cast<Replay *>(ctx);
	if (r->ready.empty()) {
		// Nothing more will come: wait out the caller's timeout as a silent camera would.
		if (timeout_ms > 0) {
			struct timespec d = {timeout_ms / 1000, (long)(timeout_ms % 1000) * 1000000L};
			nanosleep(&d, nullptr);
		}
		return -ETIMEDOUT;
	}
	*ret = r->ready.front();
	r->ready.pop_front();
	return 0;
}

int replay_disarm(void *ctx)
{
	clear_ready(static_cast<Replay *>(ctx));
	return 0;
}

} // namespace

extern "C" const struct fscan_camera_ops fscan_camera_replay_ops = {
	"replay", replay_open, replay_close, replay_count, replay_info, replay_configure,
	replay_arm, replay_next_frame, replay_disarm,
};
