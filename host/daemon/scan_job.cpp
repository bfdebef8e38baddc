#include "daemon/scan_job.hpp"

#include "common/version.hpp"
#include "daemon/clinic_output.hpp"
#include "daemon/clock.hpp"

#include <opencv2/imgcodecs.hpp>

#include <cerrno>
#include <cstring>
#include <sys/eventfd.h>
#include <sys/stat.h>
#include <unistd.h>

namespace facescan::daemon {

using json = nlohmann::json;
Mailbox::~Mailbox()
{
	if (fd_ >= 0)
		::close(fd_);
}

Status Mailbox::open()
{
	fd_ = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
	if (fd_ < 0)
		return Status::error(errno, std::string("eventfd: ") + std::strerror(errno));
	return Status();
}

void Mailbox::post(job::Message m)
{
	{
		std::lock_guard<std::mutex> lock(mu_);
		q_.push_back(std::move(m));
	}
	wake();
}

void Mailbox::wake()
{
	uint64_t one = 1;
	if (fd_ >= 0 && write(fd_, &one, sizeof one) < 0) {
		// counter saturated: a wake-up is pending anyway
	}
}

std::deque<job::Message> Mailbox::take()
{
	uint64_t n;
	if (read(fd_, &n, sizeof n) < 0) {
		// EAGAIN: nothing new
	}
	std::deque<job::Message> batch;
	std::lock_guard<std::mutex> lock(mu_);
	batch.swap(q_);
	return batch;
}

std::string capture_kept(const std::string &spool_dir, const std::string &base)
{
	const std::string dir = spool_dir + "/captures/" + base;
	struct stat st;
	if (base.empty() || stat(dir.c_str(), &st) < 0 || !S_ISDIR(st.st_mode))
		return "";
	return "; capture kept in " + dir + " for an offline retry";
}

void Worker::start_scan(json record)
{
	delivery_ = false;
	thread_ = std::thread([this, rec = std::move(record)] { scan(rec); });
}

void Worker::start_delivery()
{
	delivery_ = true;
	stop_delivery_ = false;
	thread_ = std::thread([this] { deliver(); });
}

void Worker::deliver()
{
	job::DeliveryDone done;
	Status s = spool_.deliver(&done.scans, &stop_delivery_);
	if (!stop_delivery_)
		clinic::retry_pacs(cfg_); // after the share: a late send can then record itself in the metadata
	if (!s.ok())
		done.error = s.message();
	mailbox_.post(std::move(done));
}

void Worker::scan(const json &rec)
{
	const std::string id = rec["scan_id"];
	const std::string base = rec["base"];
	// capture
	auto t0 = Clock::now();
	Capture cap;
	Status s = be_.cameras->prepare_at_arm() ? Status() : be_.cameras->prepare();
	if (!s.ok()) {
		mailbox_.post(job::Failed{"capturing", "cameras: " + s.message(), true});
		return;
	}
	TriggerReport report;
	s = be_.mcu->fire(cfg_.mcu_timeout_ms, &report);
	if (!s.ok()) {
		mailbox_.post(job::Failed{"capturing", s.message(), true});
		return;
	}
	s = be_.cameras->collect(report, cfg_.capture_timeout_ms, &cap);
	if (s.ok())
		s = check_capture(cap, be_.cameras->count(), cfg_.max_frame_skew_us);
	if (!s.ok()) {
		mailbox_.post(job::Failed{"capturing", "cameras: " + s.message(), true});
		return;
	}
	cap.report = report;
	cap.scan_name = base;
	double capture_ms = ms_since(t0);
	mailbox_.post(job::Captured{capture_ms,
				    "[1/3] captured " + std::to_string(cap.frames.size()) + " frames of trigger " +
					    std::to_string(report.sequence) + " in " +
					    std::to_string(static_cast<long>(capture_ms)) + " ms",
				    report});

	// reconstruction
	auto t1 = Clock::now();
	ReconOutput out;
	s = be_.recon->run(cap, &out);
	if (!s.ok()) {
		mailbox_.post(job::Failed{"reconstructing", "reconstruction: " + s.message(), false});
		return;
	}
	double recon_ms = ms_since(t1);
	// The worker backend keeps a whole set itself (keep_captures); others get the frames.
	if (cfg_.keep_captures &&
	    access((cfg_.spool_dir + "/captures/" + base + "/calibration.yaml").c_str(), F_OK) != 0)
		keep_capture(base, cap);
	json recon_stages = json::object();
	for (const auto &st : out.stage_ms)
		recon_stages[st.first] = st.second;
	job::Reconstructed r{recon_ms,
			     "[2/3] reconstructed " + std::to_string(out.vertices) + " vertices in " +
				     std::to_string(static_cast<long>(recon_ms)) + " ms",
			     out.vertices, out.faces, out.stage_ms, {}};
	if (out.quality.is_object() && out.quality.value("warnings", json::array()).is_array())
		for (const auto &w : out.quality["warnings"])
			if (w.is_string())
				r.warnings.push_back(w.get<std::string>());
	mailbox_.post(std::move(r));

	// writing: spool (the commit point), then the share
	auto t2 = Clock::now();
	json meta = {{"scan_id", id},
		     {"patient_id", rec["patient_id"]},
		     {"started_utc", rec["started_utc"]},
		     {"software_version", version()},
		     {"mode", mode_name(cfg_.mode)},
		     {"stage_ms", {{"capture", capture_ms}, {"reconstruct", recon_ms}}},
		     {"recon_stage_ms", recon_stages},
		     {"trigger_report", report.raw},
		     {"firmware", be_.mcu->firmware_version()},
		     {"calibration_id", cap.calibration_id},
		     {"camera_backend", be_.cameras->backend_name()},
		     {"cameras", cap.meta},
		     {"recon_backend", be_.recon->backend_name()},
		     {"vertices", out.vertices},
		     {"faces", out.faces},
		     {"quality", out.quality},
		     {"files", {{"mesh", base + ".drc"}, {"texture", base + ".png"}}}};
	std::vector<SpoolFile> files = {{base + ".drc", out.drc}, {base + ".png", out.png}};
	clinic::add_outputs(cfg_, out, rec, &files, &meta); // .glb, thumbnail, .stl/.obj, DICOM, manifest
	files.push_back({base + ".json", meta.dump(1) + "\n"});
	s = spool_.put(base, id, rec["patient_id"], files);
	if (!s.ok()) {
		mailbox_.post(job::Failed{"writing", "spool: " + s.message() + capture_kept(cfg_.spool_dir, base), false});
		return;
	}
	be_.recon->release(base);
	std::vector<Delivered> delivered;
	Status d = spool_.deliver(&delivered);
	job::Written w;
	for (const Delivered &x : delivered)
		if (x.scan_id == id) {
			w.delivered = true;
			w.files = x.paths;
		}
	if (!w.delivered)
		w.spool_reason = d.ok() ? "an older spooled scan is ahead" : d.message();
	w.ms = ms_since(t2);
	mailbox_.post(std::move(w));
}

void Worker::keep_capture(const std::string &base, const Capture &cap)
{
	const std::string dir = cfg_.spool_dir + "/captures";
	mkdir(dir.c_str(), 0750);
	const std::string set = dir + "/" + base;
	if (mkdir(set.c_str(), 0750) < 0 && errno != EEXIST)
		return;
	for (const Frame &f : cap.frames)
		cv::imwrite(set + "/cam" + std::to_string(f.camera) + (f.texture ? "_texture" : "") + ".png", f.image);
	json meta = {{"scan_id", base.substr(base.rfind('_') + 1)}, {"trigger_report", cap.report.raw}};
	write_file_atomic(set, "capture.json", meta.dump(1) + "\n");
}

} // namespace facescan::daemon
