// A scanned head's volume (a CT of a real head, fetched at set-up by
// tools/install-web-deps.sh scan, never committed) placed in the simulator's head frame.
#include "sim/internal.hpp"

#include "capture/capture_set.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <sstream>

namespace facescan::sim {

namespace {

// Skin between air (-1000 HU) and soft tissue (~0 HU).
constexpr float kSkinHU = -400.f;
constexpr float kAirHU = -1024.f;
// The canonical head's nose tip (head.cpp: the nose cone's end, y = 8 - 38, z = 85 + 26 + 8.5).
const cv::Vec3f kCanonicalTip(0.f, -30.f, 119.5f);

} // namespace

Status internal::load_scan_volume(const std::string &dir, ScanVolume *ret_volume)
{
	// Through the project's one reader: a FIFO or device under these names is refused, not waited on.
	std::string header, raw;
	Status st = read_regular_file(dir + "/volume.txt", 4096, &header);
	if (st.code() == -ENOENT)
		return Status::error(-ENOENT, "no scan head in " + dir +
						      " (volume.txt, volume.raw): fetch it with tools/install-web-deps.sh scan");
	if (!st.ok())
		return Status::error(st.code(), dir + "/volume.txt: " + st.message());
	ScanVolume v;
	std::istringstream txt(header);
	txt >> v.nx >> v.ny >> v.nz >> v.spacing[0] >> v.spacing[1] >> v.spacing[2];
	if (!txt || v.nx < 8 || v.ny < 8 || v.nz < 8 || v.nx > 2048 || v.ny > 2048 || v.nz > 2048 ||
	    !(v.spacing[0] > 0.1f && v.spacing[1] > 0.1f && v.spacing[2] > 0.1f) ||
	    !(v.spacing[0] < 10 && v.spacing[1] < 10 && v.spacing[2] < 10))
		return Status::error(-EINVAL, dir + "/volume.txt: expected \"nx ny nz sx sy sz\" (8..2048 voxels, 0.1..10 mm)");
	const size_t n = size_t(v.nx) * size_t(v.ny) * size_t(v.nz);
	st = read_regular_file(dir + "/volume.raw", n * sizeof(int16_t), &raw);
	if (st.code() == -ENOENT)
		return Status::error(-ENOENT, "no scan head in " + dir +
						      " (volume.raw): fetch it with tools/install-web-deps.sh scan");
	if (!st.ok() || raw.size() != n * sizeof(int16_t))
		return Status::error(-EINVAL, dir + "/volume.raw: not " + std::to_string(n) + " int16 voxels" +
						      (st.ok() ? "" : " (" + st.message() + ")"));
	std::vector<int16_t> in(n);
	std::memcpy(in.data(), raw.data(), raw.size());
	raw.clear();
	raw.shrink_to_fit();
	// Smoothed (sigma ~1 voxel in-slice, [1 2 1]/4 across slices) so that the iso-surface keeps
	// the skin and not the CT's noise.
	v.hu.resize(n);
	const size_t plane = size_t(v.nx) * size_t(v.ny);
	std::vector<float> blurred(n);
	for (int k = 0; k < v.nz; k++) {
		cv::Mat s(v.ny, v.nx, CV_16S, in.data() + size_t(k) * plane), f;
		s.convertTo(f, CV_32F);
		cv::Mat out(v.ny, v.nx, CV_32F, blurred.data() + size_t(k) * plane);
		cv::GaussianBlur(f, out, cv::Size(5, 5), 1.0, 1.0, cv::BORDER_REPLICATE);
	}
	for (int k = 0; k < v.nz; k++) {
		const float *a = blurred.data() + size_t(std::max(k - 1, 0)) * plane;
		const float *b = blurred.data() + size_t(k) * plane;
		const float *c = blurred.data() + size_t(std::min(k + 1, v.nz - 1)) * plane;
		float *o = v.hu.data() + size_t(k) * plane;
		for (size_t q = 0; q < plane; q++)
			o[q] = 0.25f * a[q] + 0.5f * b[q] + 0.25f * c[q];
	}
	// The nose tip: the skin voxel farthest towards the face (rows grow towards it); ties averaged.
	int tip_j = -1;
	double si = 0, sk = 0, count = 0;
	for (int k = 0; k < v.nz; k++)
		for (int j = 0; j < v.ny; j++)
			for (int i = 0; i < v.nx; i++) {
				if (v.hu[size_t(k) * plane + size_t(j) * size_t(v.nx) + size_t(i)] <= kSkinHU || j < tip_j)
					continue;
				if (j > tip_j)
					tip_j = j, si = sk = count = 0;
				si += i, sk += k, count++;
			}
	if (tip_j < 0)
		return Status::error(-EINVAL, dir + "/volume.raw: no voxel above " + std::to_string(int(kSkinHU)) + " HU");
	// Head frame = index axes turned (x = ox - i sx, y = oy + k sz, z = oz + j sy), the nose tip
	// moved onto the canonical head's; the CT is in mm already, so no scale.
	const double ti = si / count, tk = sk / count;
	v.origin = cv::Vec3f(kCanonicalTip[0] + float(ti) * v.spacing[0], kCanonicalTip[1] - float(tk) * v.spacing[2],
			     kCanonicalTip[2] - float(tip_j) * v.spacing[1]);
	v.lo = cv::Vec3f(v.origin[0] - float(v.nx - 1) * v.spacing[0], v.origin[1], v.origin[2]);
	v.hi = cv::Vec3f(v.origin[0], v.origin[1] + float(v.nz - 1) * v.spacing[2],
			 v.origin[2] + float(v.ny - 1) * v.spacing[1]);
	*ret_volume = std::move(v);
	return Status();
}

float internal::scan_field(const ScanVolume &v, const cv::Vec3f &p)
{
	const float fi = (v.origin[0] - p[0]) / v.spacing[0];
	const float fj = (p[2] - v.origin[2]) / v.spacing[1];
	const float fk = (p[1] - v.origin[1]) / v.spacing[2];
	const int i0 = int(std::floor(fi)), j0 = int(std::floor(fj)), k0 = int(std::floor(fk));
	const float ti = fi - float(i0), tj = fj - float(j0), tk = fk - float(k0);
	// Air beyond the volume, so the surface closes at its faces (the CT's lowest slice is a cap).
	auto at = [&](int i, int j, int k) {
		if (i < 0 || j < 0 || k < 0 || i >= v.nx || j >= v.ny || k >= v.nz)
			return kAirHU;
		return v.hu[(size_t(k) * size_t(v.ny) + size_t(j)) * size_t(v.nx) + size_t(i)];
	};
	float hu = 0;
	for (int c = 0; c < 8; c++) {
		const int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
		const float w = (di ? ti : 1 - ti) * (dj ? tj : 1 - tj) * (dk ? tk : 1 - tk);
		if (w != 0)
			hu += w * at(i0 + di, j0 + dj, k0 + dk);
	}
	// Scaled to about a mm per unit at the skin (the CT's edge rises ~600 HU over ~2 mm).
	return (kSkinHU - hu) / 300.f;
}

} // namespace facescan::sim
