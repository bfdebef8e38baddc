#include "daemon/backends.hpp"

#include <algorithm>

namespace facescan::daemon {

Status check_capture(const Capture &capture, int cameras, int max_skew_us)
{
	for (int texture = 0; texture < 2; texture++) {
		std::vector<const Frame *> seen(static_cast<size_t>(cameras), nullptr);
		int n = 0;
		for (const Frame &f : capture.frames) {
			if (f.texture != static_cast<bool>(texture))
				continue;
			if (f.camera < 0 || f.camera >= cameras)
				return Status::error(EPROTO, "frame from unknown camera " + std::to_string(f.camera));
			if (seen[static_cast<size_t>(f.camera)])
				return Status::error(EPROTO, "camera " + std::to_string(f.camera) +
								     " delivered two frames for one trigger");
			if (f.trigger != capture.report.sequence)
				return Status::error(EPROTO, "camera " + std::to_string(f.camera) + ": frame of trigger " +
								     std::to_string(f.trigger) + ", expected " +
								     std::to_string(capture.report.sequence));
			if (f.image.empty())
				return Status::error(EPROTO, "camera " + std::to_string(f.camera) + ": empty frame");
			seen[static_cast<size_t>(f.camera)] = &f;
			n++;
		}
		if (n == 0 && texture)
			continue; // texture frames are optional
		for (int i = 0; i < cameras; i++)
			if (!seen[static_cast<size_t>(i)])
				return Status::error(EPROTO, "camera " + std::to_string(i) + ": no " +
								     (texture ? "texture" : "pattern") + " frame");
		int64_t lo = seen[0]->timestamp_ns, hi = lo;
		for (const Frame *f : seen) {
			lo = std::min(lo, f->timestamp_ns);
			hi = std::max(hi, f->timestamp_ns);
		}
		if (hi - lo > static_cast<int64_t>(max_skew_us) * 1000)
			return Status::error(EPROTO, std::string(texture ? "texture" : "pattern") +
							     " frames " + std::to_string((hi - lo) / 1000) +
							     " us apart (limit " + std::to_string(max_skew_us) + " us)");
	}
	return Status();
}

} // namespace facescan::daemon
