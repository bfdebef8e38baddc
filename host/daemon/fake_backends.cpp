#include "daemon/fake_backends.hpp"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>

namespace facescan::daemon {

// ---- Draco ---------------------------------------------------------------------------------

Status encode_draco(const std::vector<float> &xyz, const std::vector<int> &triangles, std::string *ret_bytes)
{
	if (triangles.empty() || triangles.size() % 3 || xyz.size() % 3)
		return Status::error(EINVAL, "draco: empty or ragged mesh");
	const int nv = static_cast<int>(xyz.size() / 3);
	draco::TriangleSoupMeshBuilder b;
	b.Start(static_cast<int>(triangles.size() / 3));
	const int pos = b.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
	for (size_t f = 0; f < triangles.size() / 3; f++) {
		const float *v[3];
		for (int k = 0; k < 3; k++) {
			int idx = triangles[3 * f + static_cast<size_t>(k)];
			if (idx < 0 || idx >= nv)
				return Status::error(EINVAL, "draco: vertex index out of range");
			v[k] = &xyz[3 * static_cast<size_t>(idx)];
		}
		b.SetAttributeValuesForFace(pos, draco::FaceIndex(static_cast<uint32_t>(f)), v[0], v[1], v[2]);
	}
	std::unique_ptr<draco::Mesh> mesh = b.Finalize();
	if (!mesh)
		return Status::error(EINVAL, "draco: mesh builder failed");
	draco::Encoder enc;
	enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, 14);
	enc.SetSpeedOptions(5, 5);
	draco::EncoderBuffer buf;
	draco::Status s = enc.EncodeMeshToBuffer(*mesh, &buf);
	if (!s.ok())
		return Status::error(EIO, std::string("draco: ") + s.error_msg());
	ret_bytes->assign(buf.data(), buf.size());
	return Status();
}

Status decode_draco_counts(const std::string &bytes, long *ret_vertices, long *ret_faces)
{
	draco::DecoderBuffer db;
	db.Init(bytes.data(), bytes.size());
	draco::Decoder dec;
	auto r = dec.DecodeMeshFromBuffer(&db);
	if (!r.ok())
		return Status::error(EPROTO, std::string("draco: ") + r.status().error_msg());
	*ret_vertices = static_cast<long>(r.value()->num_points());
	*ret_faces = static_cast<long>(r.value()->num_faces());
	return Status();
}

// ---- FakeReconstructor ---------------------------------------------------------------------

Status FakeReconstructor::run(const Capture &capture, ReconOutput *ret_output)
{
	if (fail_.exchange(false))
		return Status::error(EIO, "fake reconstruction failed on request");
	auto t0 = std::chrono::steady_clock::now();
	const int rings = 24, segments = 48;
	const float r = 80.0f;
	std::vector<float> xyz;
	std::vector<int> tri;
	xyz.insert(xyz.end(), {0.0f, 0.0f, r});
	for (int i = 1; i <= rings; i++) {
		float th = static_cast<float>(M_PI / 2) * static_cast<float>(i) / rings;
		for (int j = 0; j < segments; j++) {
			float ph = 2.0f * static_cast<float>(M_PI) * static_cast<float>(j) / segments;
			xyz.insert(xyz.end(), {r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph),
					       r * std::cos(th)});
		}
	}
	auto at = [&](int ring, int j) { return ring == 0 ? 0 : 1 + (ring - 1) * segments + (j % segments); };
	for (int i = 0; i < rings; i++)
		for (int j = 0; j < segments; j++) {
			if (i == 0) {
				tri.insert(tri.end(), {0, at(1, j), at(1, j + 1)});
				continue;
			}
			tri.insert(tri.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1)});
			tri.insert(tri.end(), {at(i, j), at(i + 1, j + 1), at(i, j + 1)});
		}
	auto t1 = std::chrono::steady_clock::now();
	ReconOutput out;
	Status s = encode_draco(xyz, tri, &out.drc);
	if (!s.ok())
		return s;
	auto t2 = std::chrono::steady_clock::now();
	const Frame *tex = nullptr;
	for (const Frame &f : capture.frames)
		if (f.camera == 0 && (!tex || f.texture))
			tex = &f;
	cv::Mat img = tex ? tex->image : cv::Mat(16, 16, CV_8UC3, cv::Scalar(128, 128, 128));
	std::vector<uchar> png;
	if (!cv::imencode(".png", img, png))
		return Status::error(EIO, "texture: PNG encoding failed");
	out.png.assign(png.begin(), png.end());
	auto t3 = std::chrono::steady_clock::now();
	auto ms = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
	out.vertices = static_cast<long>(xyz.size() / 3);
	out.faces = static_cast<long>(tri.size() / 3);
	out.stage_ms = {{"mesh", ms(t0, t1)}, {"draco", ms(t1, t2)}, {"texture", ms(t2, t3)}};
	out.quality = {{"note", "fake reconstruction: a fixed hemisphere, no accuracy figure"}};
	*ret_output = std::move(out);
	return Status();
}

void FakeReconstructor::fail_next_run()
{
	fail_ = true;
}

} // namespace facescan::daemon
