// PLY encode (binary little-endian) and decode (ASCII, binary little/big-endian).
#include "mesh_io/mesh_check.hpp"
#include "mesh_io/mesh_io.hpp"

#include <algorithm>
#include <cstring>
#include <sstream>

namespace facescan::mesh_io {

namespace {

template <typename T> void put(std::string *out, T v)
{
	char b[sizeof(T)];
	std::memcpy(b, &v, sizeof(T)); // the host is little-endian (x86-64, aarch64)
	out->append(b, sizeof(T));
}

enum class Fmt { Ascii, Le, Be };

struct Prop {
	std::string name;
	std::string type;	// scalar type, or the item type of a list
	std::string count_type; // non-empty for a list
};

struct Element {
	std::string name;
	size_t count = 0;
	std::vector<Prop> props;
};

int type_size(const std::string &t)
{
	if (t == "char" || t == "uchar" || t == "int8" || t == "uint8")
		return 1;
	if (t == "short" || t == "ushort" || t == "int16" || t == "uint16")
		return 2;
	if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32")
		return 4;
	if (t == "double" || t == "float64")
		return 8;
	return 0;
}

/// Reads values one by one from the body in any of the three formats.
class Reader {
public:
	Reader(const char *p, const char *end, Fmt fmt) : p_(p), end_(end), fmt_(fmt) {}
	bool read(const std::string &type, double *v)
	{
		if (fmt_ == Fmt::Ascii) {
			while (p_ < end_ && std::isspace(static_cast<unsigned char>(*p_)))
				++p_;
			if (p_ >= end_)
				return false;
			char *e = nullptr;
			std::string tok;
			const char *s = p_;
			while (p_ < end_ && !std::isspace(static_cast<unsigned char>(*p_)))
				++p_;
			tok.assign(s, p_);
			*v = std::strtod(tok.c_str(), &e);
			return e && *e == 0;
		}
		const int n = type_size(type);
		if (n == 0 || end_ - p_ < n)
			return false;
		unsigned char b[8];
		std::memcpy(b, p_, size_t(n));
		p_ += n;
		if (fmt_ == Fmt::Be)
			std::reverse(b, b + n);
		if (type == "char" || type == "int8")
			*v = double(int8_t(b[0]));
		else if (type == "uchar" || type == "uint8")
			*v = double(b[0]);
		else if (type == "short" || type == "int16") {
			int16_t x;
			std::memcpy(&x, b, 2);
			*v = x;
		} else if (type == "ushort" || type == "uint16") {
			uint16_t x;
			std::memcpy(&x, b, 2);
			*v = x;
		} else if (type == "int" || type == "int32") {
			int32_t x;
			std::memcpy(&x, b, 4);
			*v = x;
		} else if (type == "uint" || type == "uint32") {
			uint32_t x;
			std::memcpy(&x, b, 4);
			*v = x;
		} else if (type == "float" || type == "float32") {
			float x;
			std::memcpy(&x, b, 4);
			*v = x;
		} else {
			double x;
			std::memcpy(&x, b, 8);
			*v = x;
		}
		return true;
	}

private:
	const char *p_, *end_;
	Fmt fmt_;
};

} // namespace

Status encode_ply(const recon::Mesh &mesh, std::string *ret_bytes)
{
	Status s = check_mesh(mesh);
	if (!s.ok())
		return s;
	const bool nor = !mesh.normals.empty(), col = !mesh.colours.empty(), uv = !mesh.uvs.empty();
	std::ostringstream h;
	h << "ply\nformat binary_little_endian 1.0\ncomment facescan mesh, units mm\n";
	h << "element vertex " << mesh.positions.size() << "\n";
	h << "property float x\nproperty float y\nproperty float z\n";
	if (nor)
		h << "property float nx\nproperty float ny\nproperty float nz\n";
	if (col)
		h << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
	if (uv)
		h << "property float texture_u\nproperty float texture_v\n";
	h << "element face " << mesh.triangles.size() << "\n";
	h << "property list uchar int vertex_indices\nend_header\n";
	std::string out = h.str();
	for (size_t i = 0; i < mesh.positions.size(); ++i) {
		put(&out, mesh.positions[i].x);
		put(&out, mesh.positions[i].y);
		put(&out, mesh.positions[i].z);
		if (nor) {
			put(&out, mesh.normals[i].x);
			put(&out, mesh.normals[i].y);
			put(&out, mesh.normals[i].z);
		}
		if (col) {
			put(&out, mesh.colours[i][2]);
			put(&out, mesh.colours[i][1]);
			put(&out, mesh.colours[i][0]);
		}
		if (uv) {
			put(&out, mesh.uvs[i].x);
			put(&out, mesh.uvs[i].y);
		}
	}
	for (const cv::Vec3i &t : mesh.triangles) {
		put(&out, uint8_t(3));
		put(&out, int32_t(t[0]));
		put(&out, int32_t(t[1]));
		put(&out, int32_t(t[2]));
	}
	*ret_bytes = std::move(out);
	return {};
}

Status decode_ply(const void *data, size_t size, recon::Mesh *ret_mesh)
{
	const char *begin = static_cast<const char *>(data);
	const char *end = begin + size;
	const std::string marker = "end_header";
	const char *hend = std::search(begin, end, marker.begin(), marker.end());
	if (size < 4 || std::memcmp(begin, "ply", 3) != 0 || hend == end)
		return Status::error(-EINVAL, "not a PLY file (no 'ply' magic or no end_header)");
	const char *body = hend + marker.size();
	while (body < end && *body != '\n')
		++body;
	if (body < end)
		++body;

	std::istringstream hs(std::string(begin, hend));
	std::string line;
	Fmt fmt = Fmt::Ascii;
	bool have_format = false;
	std::vector<Element> elements;
	while (std::getline(hs, line)) {
		if (!line.empty() && line.back() == '\r')
			line.pop_back();
		std::istringstream ls(line);
		std::string kw;
		ls >> kw;
		if (kw == "format") {
			std::string f;
			ls >> f;
			if (f == "ascii")
				fmt = Fmt::Ascii;
			else if (f == "binary_little_endian")
				fmt = Fmt::Le;
			else if (f == "binary_big_endian")
				fmt = Fmt::Be;
			else
				return Status::error(-EINVAL, "unknown PLY format '" + f + "'");
			have_format = true;
		} else if (kw == "element") {
			Element e;
			long long count = -1;
			ls >> e.name >> count;
			if (count < 0)
				return Status::error(-EINVAL, "bad PLY element line '" + line + "'");
			e.count = size_t(count);
			elements.push_back(e);
		} else if (kw == "property") {
			if (elements.empty())
				return Status::error(-EINVAL, "PLY property before any element");
			Prop p;
			std::string t;
			ls >> t;
			if (t == "list")
				ls >> p.count_type >> p.type >> p.name;
			else {
				p.type = t;
				ls >> p.name;
			}
			if (type_size(p.type) == 0 || (!p.count_type.empty() && type_size(p.count_type) == 0))
				return Status::error(-EINVAL, "unknown PLY property type in '" + line + "'");
			elements.back().props.push_back(p);
		}
	}
	if (!have_format)
		return Status::error(-EINVAL, "PLY header has no format line");

	recon::Mesh mesh;
	Reader r(body, end, fmt);
	for (const Element &e : elements) {
		const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
		if (is_vertex) {
			mesh.positions.resize(e.count);
		}
		auto has = [&e](std::initializer_list<const char *> names) {
			for (const Prop &p : e.props)
				for (const char *n : names)
					if (p.name == n)
						return true;
			return false;
		};
		const bool nor = is_vertex && has({"nx"}), col = is_vertex && has({"red"}),
			   uv = is_vertex && has({"u", "s", "texture_u"});
		if (nor)
			mesh.normals.resize(e.count);
		if (col)
			mesh.colours.resize(e.count);
		if (uv)
			mesh.uvs.resize(e.count);
		for (size_t i = 0; i < e.count; ++i) {
			for (const Prop &p : e.props) {
				double v = 0;
				if (!p.count_type.empty()) {
					double cnt = 0;
					if (!r.read(p.count_type, &cnt) || cnt < 0)
						return Status::error(-EINVAL, "PLY body truncated in element " + e.name);
					std::vector<int> idx(static_cast<size_t>(cnt));
					for (int &x : idx) {
						if (!r.read(p.type, &v))
							return Status::error(-EINVAL, "PLY body truncated in element " + e.name);
						x = int(v);
					}
					if (is_face && (p.name == "vertex_indices" || p.name == "vertex_index"))
						for (size_t k = 2; k < idx.size(); ++k)
							mesh.triangles.emplace_back(idx[0], idx[k - 1], idx[k]);
					continue;
				}
				if (!r.read(p.type, &v))
					return Status::error(-EINVAL, "PLY body truncated in element " + e.name);
				if (!is_vertex)
					continue;
				const bool frac = p.type == "float" || p.type == "double" || p.type == "float32" ||
						  p.type == "float64";
				const uint8_t c8 = uint8_t(std::clamp(frac ? v * 255.0 + 0.5 : v, 0.0, 255.0));
				const std::string &n = p.name;
				if (n == "x")
					mesh.positions[i].x = float(v);
				else if (n == "y")
					mesh.positions[i].y = float(v);
				else if (n == "z")
					mesh.positions[i].z = float(v);
				else if (nor && n == "nx")
					mesh.normals[i].x = float(v);
				else if (nor && n == "ny")
					mesh.normals[i].y = float(v);
				else if (nor && n == "nz")
					mesh.normals[i].z = float(v);
				else if (col && n == "red")
					mesh.colours[i][2] = c8;
				else if (col && n == "green")
					mesh.colours[i][1] = c8;
				else if (col && n == "blue")
					mesh.colours[i][0] = c8;
				else if (uv && (n == "u" || n == "s" || n == "texture_u"))
					mesh.uvs[i].x = float(v);
				else if (uv && (n == "v" || n == "t" || n == "texture_v"))
					mesh.uvs[i].y = float(v);
			}
		}
	}
	if (mesh.positions.empty())
		return Status::error(-EINVAL, "PLY has no vertices");
	Status s = check_mesh(mesh);
	if (!s.ok())
		return s;
	*ret_mesh = std::move(mesh);
	return {};
}

} // namespace facescan::mesh_io
