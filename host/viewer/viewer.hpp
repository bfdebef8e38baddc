// The web viewer's server: the share's scans (and only them) to a browser on localhost, with the
// viewer page (host/viewer/page/) and the pinned three.js it runs on (build/web/node_modules,
// tools/install-web-deps.sh). cpp-httplib (Debian's libcpp-httplib-dev) does HTTP.
//
// URL space, everything else 404:
//   /  /index.html  /view.html  /viewer.js  /index.js  /style.css   the page (web_dir/page/)
//   /vendor/three/{build,examples/jsm}/...  /vendor/three/LICENSE     three.js (web_dir/node_modules/three/)
//   /api/scans                                                      the share's scans per patient (JSON)
//   /share/<patient>/<file>   (/share/<file> when serving one mesh)  a scan's files
// Path parts are checked before any file is touched: no '..', no leading '.', no '\', no
// control characters; the resolved real path must stay inside its root (a symlink out of the
// share is refused too); only scan file types are served. Refusals are 403 and name no file.
#pragma once

#include "common/status.hpp"

#include <memory>
#include <string>

namespace facescan::viewer {

struct Options {
	std::string share_dir;	 // serve this share (patients' directories of scans), or
	std::string single_mesh; // serve just this mesh file (and its siblings of the same scan)
	std::string web_dir;	 // holds page/ and node_modules/three/
	std::string bind = "127.0.0.1";
	int port = 8080;	 // 0: any free port
};

/// Where the viewer's web files are: $FACESCAN_WEB, else <dir of exe>/../web, else
/// <dir of exe>/../../web (build/bin and build/asan/bin both find build/web), else
/// <dir of exe>/../share/facescan/web (an installed PREFIX/bin, make install). -ENOENT otherwise.
Status find_web_dir(std::string *ret_dir);

/// Maps a URL path under /share/ (already percent-decoded, without the prefix) to a file of the
/// share. -EACCES for a path the rules above refuse, -ENOENT when no such file.
Status resolve_share_file(const std::string &share_dir, const std::string &rel, std::string *ret_path);

/// The share's scans as JSON: {"patients": {"<id>": [{"base", "glb", "thumbnail", "metadata"}...]}}.
std::string scan_listing_json(const std::string &share_dir);

/// An HTTP server on its own thread. start() binds (so the port is known and taken when it
/// returns) and serves until stop() or destruction.
class Server {
public:
	Server();
	~Server();
	Server(const Server &) = delete;
	Server &operator=(const Server &) = delete;
	/// -EINVAL bad options, -ENOENT missing share/mesh/web files, -EADDRINUSE when it cannot bind.
	Status start(const Options &options, int *ret_port);
	void stop();

private:
	struct Impl;
	std::unique_ptr<Impl> impl_;
};

} // namespace facescan::viewer
