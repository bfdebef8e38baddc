#include "viewer/viewer.hpp"
#include "viewer/httplib.hpp"

#include <nlohmann/json.hpp>

#include <dirent.h>
#include <limits.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>
#include <vector>

namespace facescan::viewer {

namespace {

bool ends_with(const std::string &s, const std::string &e)
{
	return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

// One path component as the rules allow it.
bool safe_part(const std::string &p)
{
	if (p.empty() || p.size() > 255 || p[0] == '.')
		return false;
	for (char ch : p) {
		const unsigned char u = static_cast<unsigned char>(ch);
		if (u < 0x20 || u == 0x7f || ch == '\\' || ch == '/' || ch == ':')
			return false;
	}
	return true;
}

bool split_safe(const std::string &rel, std::vector<std::string> *parts)
{
	parts->clear();
	std::string cur;
	for (size_t i = 0; i <= rel.size(); ++i) {
		if (i == rel.size() || rel[i] == '/') {
			if (!safe_part(cur))
				return false;
			parts->push_back(cur);
			cur.clear();
		} else {
			cur.push_back(rel[i]);
		}
	}
	return !parts->empty();
}

std::string real(const std::string &p)
{
	char buf[PATH_MAX];
	return realpath(p.c_str(), buf) ? std::string(buf) : std::string();
}

bool inside(const std::string &root_real, const std::string &path_real)
{
	return !root_real.empty() && path_real.size() > root_real.size() + 1 &&
	       path_real.compare(0, root_real.size(), root_real) == 0 && path_real[root_real.size()] == '/';
}

bool is_dir(const std::string &p)
{
	struct stat st;
	return stat(p.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool is_file(const std::string &p)
{
	struct stat st;
	return stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

const char *mime_of(const std::string &p)
{
	static const std::pair<const char *, const char *> table[] = {
		{".html", "text/html; charset=utf-8"}, {".js", "text/javascript; charset=utf-8"},
		{".css", "text/css; charset=utf-8"},   {".wasm", "application/wasm"},
		{".glb", "model/gltf-binary"},	       {".png", "image/png"},
		{".json", "application/json"},	       {".drc", "application/octet-stream"},
		{".stl", "model/stl"},		       {".obj", "model/obj"},
		{".mtl", "model/mtl"},		       {".dcm", "application/dicom"},
	};
	for (const auto &[ext, mime] : table)
		if (ends_with(p, ext))
			return mime;
	return nullptr;
}

bool share_type(const std::string &p)
{
	for (const char *ext : {".glb", ".png", ".json", ".drc", ".stl", ".obj", ".mtl", ".dcm"})
		if (ends_with(p, ext))
			return true;
	return false;
}

std::vector<std::string> list_dir(const std::string &dir)
{
	std::vector<std::string> out;
	if (DIR *d = opendir(dir.c_str())) {
		while (dirent *e = readdir(d))
			if (safe_part(e->d_name))
				out.emplace_back(e->d_name);
		closedir(d);
	}
	std::sort(out.begin(), out.end());
	return out;
}

bool read_all(const std::string &path, std::string *ret)
{
	std::ifstream in(path, std::ios::binary);
	if (!in)
		return false;
	std::ostringstream ss;
	ss << in.rdbuf();
	*ret = ss.str();
	return !in.bad();
}

nlohmann::json scans_in(const std::string &dir, const std::string &url_prefix)
{
	nlohmann::json list = nlohmann::json::array();
	for (const std::string &f : list_dir(dir)) {
		if (!ends_with(f, ".glb") || !is_file(dir + "/" + f))
			continue;
		const std::string base = f.substr(0, f.size() - 4);
		nlohmann::json s = {{"base", base}, {"glb", url_prefix + f}};
		if (is_file(dir + "/" + base + "_thumb.png"))
			s["thumbnail"] = url_prefix + base + "_thumb.png";
		if (is_file(dir + "/" + base + ".json"))
			s["metadata"] = url_prefix + base + ".json";
		list.push_back(s);
	}
	return list;
}

} // namespace

Status find_web_dir(std::string *ret_dir)
{
	std::vector<std::string> candidates;
	if (const char *env = std::getenv("FACESCAN_WEB"))
		candidates.emplace_back(env);
	const std::string exe = real("/proc/self/exe");
	const std::string exe_dir = exe.substr(0, exe.rfind('/'));
	candidates.push_back(exe_dir + "/../web");		   // build/bin
	candidates.push_back(exe_dir + "/../../web");		   // build/asan/bin
	candidates.push_back(exe_dir + "/../share/facescan/web"); // PREFIX/bin (make install)
	for (const std::string &c : candidates)
		if (is_file(c + "/page/view.html") && is_file(c + "/node_modules/three/build/three.module.js")) {
			*ret_dir = real(c);
			return {};
		}
	return Status::error(-ENOENT, "viewer files not found (set FACESCAN_WEB, or run "
				      "tools/install-web-deps.sh web to fill build/web; "
				      "installed: PREFIX/share/facescan/web)");
}

Status resolve_share_file(const std::string &share_dir, const std::string &rel, std::string *ret_path)
{
	std::vector<std::string> parts;
	if (!split_safe(rel, &parts) || parts.size() > 2 || !share_type(parts.back()))
		return Status::error(-EACCES, "path refused");
	std::string path = share_dir;
	for (const std::string &p : parts)
		path += "/" + p;
	const std::string rp = real(path);
	if (rp.empty())
		return Status::error(-ENOENT, "no such file");
	if (!inside(real(share_dir), rp) || !is_file(rp))
		return Status::error(-EACCES, "path refused");
	*ret_path = rp;
	return {};
}

std::string scan_listing_json(const std::string &share_dir)
{
	nlohmann::json patients = nlohmann::json::object();
	for (const std::string &p : list_dir(share_dir)) {
		const std::string dir = share_dir + "/" + p;
		if (!is_dir(dir))
			continue;
		nlohmann::json scans = scans_in(dir, "/share/" + p + "/");
		if (!scans.empty())
			patients[p] = scans;
	}
	return nlohmann::json({{"patients", patients}}).dump(1);
}

struct Server::Impl {
	httplib::Server http;
	std::thread thread;
};

Server::Server() = default;
Server::~Server()
{
	stop();
}

void Server::stop()
{
	if (!impl_)
		return;
	impl_->http.stop();
	if (impl_->thread.joinable())
		impl_->thread.join();
	impl_.reset();
}

Status Server::start(const Options &opt, int *ret_port)
{
	stop();
	if (opt.share_dir.empty() == opt.single_mesh.empty())
		return Status::error(-EINVAL, "viewer: give a share directory or one mesh");
	if (opt.port < 0 || opt.port > 65535)
		return Status::error(-EINVAL, "viewer: port outside 0..65535");
	std::string share = opt.share_dir, mesh_name;
	if (!opt.single_mesh.empty()) {
		const std::string rp = real(opt.single_mesh);
		if (rp.empty() || !is_file(rp) || !ends_with(rp, ".glb"))
			return Status::error(-ENOENT, opt.single_mesh + ": not a .glb file");
		share = rp.substr(0, rp.rfind('/'));
		mesh_name = rp.substr(rp.rfind('/') + 1);
	}
	share = real(share);
	if (share.empty() || !is_dir(share))
		return Status::error(-ENOENT, opt.share_dir + ": not a directory");
	const std::string web = real(opt.web_dir);
	if (web.empty() || !is_file(web + "/page/view.html"))
		return Status::error(-ENOENT, opt.web_dir + ": no viewer page (page/view.html)");
	const std::string three = real(web + "/node_modules/three");
	if (three.empty())
		return Status::error(-ENOENT, opt.web_dir + ": no three.js (node_modules/three)");

	auto impl = std::make_unique<Impl>();
	httplib::Server &h = impl->http;
	h.set_default_headers({{"X-Content-Type-Options", "nosniff"}, {"Cache-Control", "no-store"}});
	auto send_file = [](const std::string &path, httplib::Response &res) {
		std::string body;
		const char *mime = mime_of(path);
		if (!mime || !read_all(path, &body)) {
			res.status = 404;
			return;
		}
		res.set_content(body, mime);
	};
	auto refuse = [](httplib::Response &res, int status) {
		res.status = status;
		res.set_content(status == 403 ? "refused\n" : "not found\n", "text/plain");
	};
	h.Get(R"(/(index\.html|view\.html|viewer\.js|index\.js|style\.css)?)",
	      [web, send_file](const httplib::Request &req, httplib::Response &res) {
		      const std::string name = req.matches[1].str().empty() ? "index.html" : req.matches[1].str();
		      send_file(web + "/page/" + name, res);
	      });
	h.Get(R"(/vendor/three/(.+))", [three, send_file, refuse](const httplib::Request &req, httplib::Response &res) {
		const std::string rel = req.matches[1].str();
		std::vector<std::string> parts;
		const bool allowed = rel == "LICENSE" || rel.compare(0, 6, "build/") == 0 ||
				     rel.compare(0, 13, "examples/jsm/") == 0;
		if (!allowed || !split_safe(rel, &parts))
			return refuse(res, 403);
		const std::string rp = real(three + "/" + rel);
		if (rp.empty())
			return refuse(res, 404);
		if (!inside(three, rp) || !is_file(rp))
			return refuse(res, 403);
		if (rel == "LICENSE") {
			std::string body;
			read_all(rp, &body);
			res.set_content(body, "text/plain; charset=utf-8");
			return;
		}
		send_file(rp, res);
	});
	h.Get("/api/scans", [share, mesh_name](const httplib::Request &, httplib::Response &res) {
		if (mesh_name.empty()) {
			res.set_content(scan_listing_json(share), "application/json");
			return;
		}
		nlohmann::json one = {{"patients", {{"", scans_in(share, "/share/")}}}};
		res.set_content(one.dump(1), "application/json");
	});
	h.Get(R"(/share/(.+))", [share, mesh_name, send_file, refuse](const httplib::Request &req, httplib::Response &res) {
		const std::string rel = req.matches[1].str();
		// One mesh: only the files of that scan (same stem) beside it.
		if (!mesh_name.empty()) {
			const std::string stem = mesh_name.substr(0, mesh_name.size() - 4);
			if (rel.find('/') != std::string::npos || rel.compare(0, stem.size(), stem) != 0)
				return refuse(res, 403);
		}
		std::string path;
		Status s = resolve_share_file(share, rel, &path);
		if (!s.ok())
			return refuse(res, s.code() == -ENOENT ? 404 : 403);
		send_file(path, res);
	});
	// Anything else, and anything not GET, is not ours to answer.
	h.set_error_handler([](const httplib::Request &, httplib::Response &res) {
		if (res.body.empty())
			res.set_content(res.status == 403 ? "refused\n" : "not found\n", "text/plain");
	});

	int port = opt.port;
	if (port == 0) {
		port = h.bind_to_any_port(opt.bind);
		if (port < 0)
			return Status::error(-EADDRINUSE, "viewer: cannot bind " + opt.bind);
	} else if (!h.bind_to_port(opt.bind, port)) {
		return Status::error(-EADDRINUSE, "viewer: cannot bind " + opt.bind + ":" + std::to_string(port));
	}
	impl->thread = std::thread([p = &impl->http] { p->listen_after_bind(); });
	impl_ = std::move(impl);
	*ret_port = port;
	return {};
}

} // namespace facescan::viewer
