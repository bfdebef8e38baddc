// Meshes: checks, transforms, the plane and sphere test objects, PLY output.
#include "sim/internal.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace facescan::sim {

namespace internal {

Status check_mesh(const Mesh &mesh, const std::string &what)
{
	size_t n = mesh.vertices.size();
	if (n == 0 || mesh.triangles.empty())
		return Status::error(-EINVAL, what + ": empty mesh");
	if (n > size_t(INT32_MAX))
		return Status::error(-EINVAL, what + ": too many vertices");
	if (!mesh.normals.empty() && mesh.normals.size() != n)
		return Status::error(-EINVAL, what + ": normals size differs from vertices");
	if (!mesh.colors.empty() && mesh.colors.size() != n)
		return Status::error(-EINVAL, what + ": colors size differs from vertices");
	if (!mesh.uv.empty() && mesh.uv.size() != n)
		return Status::error(-EINVAL, what + ": uv size differs from vertices");
	for (size_t i = 0; i < mesh.triangles.size(); i++)
		for (int k = 0; k < 3; k++) {
			int v = mesh.triangles[i][k];
			if (v < 0 || size_t(v) >= n)
				return Status::error(-EINVAL, what + ": triangle " + std::to_string(i) +
								      " has vertex index " + std::to_string(v) +
								      " out of range");
		}
	for (const cv::Vec3f &v : mesh.vertices)
		if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
			return Status::error(-EINVAL, what + ": non-finite vertex");
	return Status();
}

uint64_t mix64(uint64_t x)
{
	// splitmix64's finaliser.
	x += 0x9e3779b97f4a7c15ULL;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
	return x ^ (x >> 31);
}

double gaussian(uint64_t key, uint64_t index)
{
	double u1 = uniform01(key, 2 * index), u2 = uniform01(key, 2 * index + 1);
	return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

} // namespace internal

void transform_mesh(const cv::Matx33d &R, const cv::Vec3d &t, Mesh *mesh)
{
	cv::Matx33f Rf = R;
	cv::Vec3f tf = t;
	for (cv::Vec3f &v : mesh->vertices)
		v = Rf * v + tf;
	for (cv::Vec3f &n : mesh->normals)
		n = Rf * n;
}

Mesh make_plane(double width_mm, double height_mm, int subdivisions)
{
	Mesh m;
	int s = subdivisions < 1 ? 1 : subdivisions;
	for (int j = 0; j <= s; j++)
		for (int i = 0; i <= s; i++) {
			float u = float(i) / float(s), v = float(j) / float(s);
			m.vertices.push_back(cv::Vec3f(float((u - 0.5) * width_mm),
						       float((0.5 - v) * height_mm), 0.f));
			m.normals.push_back(cv::Vec3f(0, 0, 1));
			m.uv.push_back(cv::Vec2f(u, v));
		}
	for (int j = 0; j < s; j++)
		for (int i = 0; i < s; i++) {
			int a = j * (s + 1) + i, b = a + 1, c = a + s + 1, d = c + 1;
			// Counter-clockwise seen from +z (v grows downwards, y upwards).
			m.triangles.push_back(cv::Vec3i(a, c, b));
			m.triangles.push_back(cv::Vec3i(b, c, d));
		}
	return m;
}

Mesh make_sphere(const cv::Vec3d &centre, double radius_mm, int rings, int segments)
{
	Mesh m;
	rings = rings < 4 ? 4 : rings;
	segments = segments < 6 ? 6 : segments;
	const double pi = 3.14159265358979323846;
	for (int r = 0; r <= rings; r++) {
		double th = pi * r / rings;
		for (int s = 0; s <= segments; s++) {
			double ph = 2 * pi * s / segments;
			cv::Vec3d n(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
			m.vertices.push_back(cv::Vec3f(centre + radius_mm * n));
			m.normals.push_back(cv::Vec3f(n));
			m.uv.push_back(cv::Vec2f(float(s) / segments, float(r) / rings));
		}
	}
	for (int r = 0; r < rings; r++)
		for (int s = 0; s < segments; s++) {
			int a = r * (segments + 1) + s, b = a + 1, c = a + segments + 1, d = c + 1;
			if (r > 0)
				m.triangles.push_back(cv::Vec3i(a, b, c));
			if (r < rings - 1)
				m.triangles.push_back(cv::Vec3i(b, d, c));
		}
	return m;
}

Status write_ply(const std::string &path, const Mesh &mesh)
{
	Status st = internal::check_mesh(mesh, path);
	if (!st.ok())
		return st;
	bool normals = mesh.normals.size() == mesh.vertices.size();
	std::string header = "ply\nformat binary_little_endian 1.0\ncomment facescan simulator ground "
			     "truth, units mm, world frame\nelement vertex " +
			     std::to_string(mesh.vertices.size()) +
			     "\nproperty float x\nproperty float y\nproperty float z\n";
	if (normals)
		header += "property float nx\nproperty float ny\nproperty float nz\n";
	header += "element face " + std::to_string(mesh.triangles.size()) +
		  "\nproperty list uchar int vertex_indices\nend_header\n";
	std::string data = header;
	size_t vsize = normals ? 24 : 12;
	data.reserve(header.size() + mesh.vertices.size() * vsize + mesh.triangles.size() * 13);
	for (size_t i = 0; i < mesh.vertices.size(); i++) {
		data.append(reinterpret_cast<const char *>(&mesh.vertices[i][0]), 12);
		if (normals)
			data.append(reinterpret_cast<const char *>(&mesh.normals[i][0]), 12);
	}
	for (const cv::Vec3i &t : mesh.triangles) {
		data.push_back(char(3));
		data.append(reinterpret_cast<const char *>(&t[0]), 12);
	}
	return write_file_atomic(path, data.data(), data.size());
}

void internal::keep_largest_piece(Mesh *mesh)
{
	// Union-find over vertices joined by triangles.
	std::vector<int> parent(mesh->vertices.size());
	for (size_t i = 0; i < parent.size(); i++)
		parent[i] = int(i);
	auto find = [&](int a) {
		while (parent[size_t(a)] != a)
			a = parent[size_t(a)] = parent[size_t(parent[size_t(a)])];
		return a;
	};
	for (const cv::Vec3i &t : mesh->triangles)
		for (int e = 1; e < 3; e++) {
			int a = find(t[0]), b = find(t[e]);
			if (a != b)
				parent[size_t(std::max(a, b))] = std::min(a, b);
		}
	std::vector<size_t> size(parent.size(), 0);
	for (const cv::Vec3i &t : mesh->triangles)
		size[size_t(find(t[0]))]++;
	const int keep = int(std::max_element(size.begin(), size.end()) - size.begin());
	Mesh out;
	std::vector<int> map(mesh->vertices.size(), -1);
	for (const cv::Vec3i &t : mesh->triangles) {
		if (find(t[0]) != keep)
			continue;
		cv::Vec3i u;
		for (int c = 0; c < 3; c++) {
			int &m = map[size_t(t[c])];
			if (m < 0) {
				m = int(out.vertices.size());
				out.vertices.push_back(mesh->vertices[size_t(t[c])]);
				if (!mesh->normals.empty())
					out.normals.push_back(mesh->normals[size_t(t[c])]);
				if (!mesh->colors.empty())
					out.colors.push_back(mesh->colors[size_t(t[c])]);
			}
			u[c] = m;
		}
		out.triangles.push_back(u);
	}
	*mesh = std::move(out);
}

} // namespace facescan::sim
