#include "daemon/clinic_output.hpp"
#include "daemon/clock.hpp"
#include "daemon/output.hpp"

#include "capture/capture_set.hpp"
#include "common/version.hpp"
#include "dicom/dicom.hpp"
#include "mesh_io/mesh_io.hpp"
#include "preview/preview.hpp"

#include <openssl/evp.h>
#include <opencv2/imgcodecs.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <sstream>

namespace facescan::daemon::clinic {

namespace {

// One sender at a time: the scan worker and the retry both flush the DICOM spool.
std::mutex g_outbox_mutex;

dicom::Pacs pacs_of(const Config &cfg)
{
	return dicom::Pacs{cfg.pacs_calling_ae, cfg.pacs_called_ae, cfg.pacs_host, cfg.pacs_port, cfg.pacs_timeout_s};
}

std::string now_iso()
{
	return utc_iso(std::chrono::system_clock::now());
}

std::string str(const nlohmann::json &j, const char *key)
{
	return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string();
}

} // namespace

std::string sha256_hex(const std::string &bytes)
{
	unsigned char md[EVP_MAX_MD_SIZE];
	unsigned int n = 0;
	if (EVP_Digest(bytes.data(), bytes.size(), md, &n, EVP_sha256(), nullptr) != 1)
		return "";
	std::string hex;
	char b[3];
	for (unsigned i = 0; i < n; ++i) {
		std::snprintf(b, sizeof b, "%02x", md[i]);
		hex += b;
	}
	return hex;
}

void add_outputs(const Config &cfg, const ReconOutput &out, const nlohmann::json &rec, std::vector<SpoolFile> *files,
		 nlohmann::json *meta)
{
	const std::string base = str(rec, "base"), patient = str(rec, "patient_id");
	nlohmann::json errors = nlohmann::json::object();
	std::vector<std::pair<std::string, std::string>> roles = {{base + ".drc", "mesh"}, {base + ".png", "texture"}};
	auto add = [&](const std::string &name, const char *role, std::string bytes) {
		files->push_back({name, std::move(bytes)});
		roles.emplace_back(name, role);
	};
	const bool want_mesh = cfg.output_glb || cfg.output_thumbnail || cfg.output_stl || cfg.output_obj ||
			       cfg.output_dicom || !cfg.pacs_called_ae.empty();
	recon::Mesh mesh;
	Status s;
	if (want_mesh) {
		s = mesh_io::decode_draco(out.drc.data(), out.drc.size(), &mesh);
		if (s.ok() && !out.png.empty())
			mesh.texture = cv::imdecode(std::vector<unsigned char>(out.png.begin(), out.png.end()),
						    cv::IMREAD_COLOR);
		if (!s.ok())
			errors["mesh"] = s.message();
	}
	const bool have_mesh = want_mesh && s.ok();
	auto timed = [&](const char *what, auto fn) {
		const auto t0 = Clock::now();
		Status r = fn();
		(*meta)["output_ms"][what] = ms_since(t0);
		if (!r.ok())
			errors[what] = r.message();
	};
	if (have_mesh && cfg.output_glb)
		timed("glb", [&] {
			std::string b;
			Status r = mesh_io::encode_glb(mesh, mesh_io::DracoOptions(), &b);
			if (r.ok())
				add(base + ".glb", "gltf", std::move(b));
			return r;
		});
	if (have_mesh && cfg.output_thumbnail)
		timed("thumbnail", [&] {
			cv::Mat img;
			Status r = preview::thumbnail(mesh, 240, 300, &img);
			std::vector<unsigned char> png;
			if (r.ok() && !cv::imencode(".png", img, png))
				r = Status::error(-EIO, "thumbnail: PNG encoding failed");
			if (r.ok())
				add(base + "_thumb.png", "thumbnail", std::string(png.begin(), png.end()));
			return r;
		});
	std::string stl;
	if (have_mesh && (cfg.output_stl || cfg.output_dicom || !cfg.pacs_called_ae.empty()))
		timed("stl", [&] {
			Status r = mesh_io::encode_stl(mesh, mesh_io::Units::mm, &stl);
			if (r.ok() && cfg.output_stl)
				add(base + ".stl", "stl", stl);
			return r;
		});
	if (have_mesh && cfg.output_obj)
		timed("obj", [&] {
			// The OBJ writer works on files; it writes into a private directory of the spool
			// and the bytes go through the spool like every other file.
			const std::string dir = cfg.spool_dir + "/obj-" + base;
			mkdir(dir.c_str(), 0750);
			mesh_io::ObjFiles of;
			Status r = mesh_io::write_obj(dir + "/" + base + ".obj", mesh, mesh_io::Units::mm, base + ".png",
						      false, &of);
			std::string obj, mtl;
			if (r.ok())
				r = mesh_io::read_file_bytes(of.obj, &obj);
			if (r.ok())
				r = mesh_io::read_file_bytes(of.mtl, &mtl);
			unlink((dir + "/" + base + ".obj").c_str());
			unlink((dir + "/" + base + ".mtl").c_str());
			rmdir(dir.c_str());
			if (r.ok()) {
				add(base + ".mtl", "obj-material", std::move(mtl));
				add(base + ".obj", "obj", std::move(obj));
			}
			return r;
		});

	if (!stl.empty()) {
		nlohmann::json dj;
		timed("dicom", [&] {
			dicom::Subject who{patient, str(rec, "dicom_name"), str(rec, "dicom_accession"),
					   str(rec, "dicom_study_uid")};
			dicom::Equipment eq;
			eq.software_version = version();
			std::string dcm;
			dicom::Instance inst;
			Status r = dicom::encode_stl_instance(stl, who, eq, std::chrono::system_clock::now(), &dcm, &inst);
			if (!r.ok())
				return r;
			dj = {{"sop_class_uid", inst.sop_class_uid},
			      {"sop_instance_uid", inst.sop_instance_uid},
			      {"study_instance_uid", inst.study_uid},
			      {"series_instance_uid", inst.series_uid}};
			if (cfg.output_dicom) {
				add(base + ".dcm", "dicom", dcm);
				dj["share"] = base + ".dcm";
			}
			if (cfg.pacs_called_ae.empty())
				return Status();
			const std::string where = cfg.pacs_called_ae + "@" + cfg.pacs_host + ":" + std::to_string(cfg.pacs_port);
			std::lock_guard<std::mutex> lock(g_outbox_mutex);
			dicom::Outbox box(cfg.spool_dir + "/dicom");
			std::string queued;
			r = box.open();
			if (r.ok())
				r = box.put(inst.sop_instance_uid, dcm, cfg.share_dir + "/" + patient + "/" + base + ".json",
					    &queued);
			if (!r.ok())
				return r;
			std::vector<dicom::Outbox::Sent> sent;
			const Status f = box.flush(pacs_of(cfg), &sent);
			bool ours = false;
			for (const auto &x : sent)
				ours = ours || x.sop_instance_uid == inst.sop_instance_uid;
			if (ours)
				dj["pacs"] = {{"ae", where}, {"state", "sent"}, {"sent_utc", now_iso()}};
			else
				dj["pacs"] = {{"ae", where}, {"state", "spooled"}, {"spool", queued},
					      {"reason", f.ok() ? "older instances are ahead" : f.message()}};
			return Status();
		});
		if (!dj.empty())
			(*meta)["dicom"] = dj;
	}

	nlohmann::json manifest = nlohmann::json::array();
	for (const auto &[name, role] : roles)
		for (const SpoolFile &f : *files)
			if (f.name == name)
				manifest.push_back({{"file", name}, {"role", role}, {"bytes", f.contents.size()},
						    {"sha256", sha256_hex(f.contents)}});
	(*meta)["manifest"] = manifest;
	if (!errors.empty())
		(*meta)["output_errors"] = errors;
}

bool pacs_pending(const Config &cfg)
{
	if (cfg.pacs_called_ae.empty())
		return false;
	return !dicom::Outbox(cfg.spool_dir + "/dicom").pending().empty();
}

Status retry_pacs(const Config &cfg)
{
	if (cfg.pacs_called_ae.empty())
		return {};
	std::lock_guard<std::mutex> lock(g_outbox_mutex);
	dicom::Outbox box(cfg.spool_dir + "/dicom");
	std::vector<dicom::Outbox::Sent> sent;
	const Status s = box.flush(pacs_of(cfg), &sent);
	for (const dicom::Outbox::Sent &x : sent) {
		// Only a metadata file inside the share, as the note was written by add_outputs().
		if (x.note.compare(0, cfg.share_dir.size() + 1, cfg.share_dir + "/") != 0)
			continue;
		std::string text;
		if (!mesh_io::read_file_bytes(x.note, &text).ok())
			continue; // the scan itself still waits in the spool: its metadata says "spooled"
		nlohmann::json meta = nlohmann::json::parse(text, nullptr, false);
		if (meta.is_discarded() || !meta.contains("dicom"))
			continue;
		meta["dicom"]["pacs"]["state"] = "sent";
		meta["dicom"]["pacs"]["sent_utc"] = now_iso();
		meta["dicom"]["pacs"].erase("spool");
		meta["dicom"]["pacs"].erase("reason");
		const std::string body = meta.dump(1) + "\n";
		facescan::write_file_atomic(x.note, body.data(), body.size());
	}
	return s;
}

} // namespace facescan::daemon::clinic
