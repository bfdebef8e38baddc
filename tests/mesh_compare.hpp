// Comparing a mesh read back (or decoded) with the one written: the tests of every mesh format
// use these two, so a reader's vertex order and a writer's quantisation are judged the same way.
#pragma once

#include "recon/types.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <set>
#include <vector>

namespace facescan::testing {

/// Nearest original vertex of every vertex of `got`; -1 (and a line on stdout) where none is
/// within `tol`. `ret_worst`, if given, gets the largest nearest distance.
inline std::vector<int> match_vertices(const recon::Mesh &orig, const recon::Mesh &got, double tol,
				       double *ret_worst = nullptr)
{
	std::vector<int> map(got.positions.size(), -1);
	double worst = 0;
	for (size_t i = 0; i < got.positions.size(); ++i) {
		double best = 1e30;
		for (size_t k = 0; k < orig.positions.size(); ++k) {
			const cv::Point3f d = got.positions[i] - orig.positions[k];
			const double e = std::sqrt(double(d.dot(d)));
			if (e < best) {
				best = e;
				map[i] = int(k);
			}
		}
		worst = std::max(worst, best);
		if (best > tol) {
			std::printf("vertex %zu off by %.5f mm > %.5f\n", i, best, tol);
			map[i] = -1;
		}
	}
	if (ret_worst)
		*ret_worst = worst;
	return map;
}

/// The triangles as a set, each renumbered through `map` (when given) and rotated so the smallest
/// index leads: equal sets mean the same triangles with the same winding.
inline std::set<std::array<int, 3>> face_set(const std::vector<cv::Vec3i> &tris, const std::vector<int> *map)
{
	std::set<std::array<int, 3>> s;
	for (const cv::Vec3i &t : tris) {
		std::array<int, 3> f{{t[0], t[1], t[2]}};
		if (map)
			for (int &v : f)
				v = (*map)[size_t(v)];
		while (f[0] > f[1] || f[0] > f[2])
			f = {{f[1], f[2], f[0]}};
		s.insert(f);
	}
	return s;
}

} // namespace facescan::testing
