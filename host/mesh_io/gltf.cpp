// glTF 2.0 binary (.glb) of recon::Mesh: tinygltf builds and parses the container (JSON chunk,
// BIN chunk, accessors, material); the geometry is one Draco bitstream from encode_draco_ids()
// referenced by KHR_draco_mesh_compression, which three.js' DRACOLoader, Blender and the
// Khronos validator read. Debian's tinygltf is built without Draco, so decoding the primitive
// is ours too (decode_draco_ids()).
#include "mesh_io/draco_ids.hpp"
#include "mesh_io/mesh_check.hpp"
#include "mesh_io/mesh_io.hpp"

#include "capture/capture_set.hpp"

#include <opencv2/imgcodecs.hpp>

#include "mesh_io/tinygltf.hpp"

#include <nlohmann/json.hpp>

#include <cfloat>
#include <cstring>
#include <sstream>

namespace facescan::mesh_io {

namespace {

constexpr const char *kDraco = "KHR_draco_mesh_compression";
constexpr double kMetresPerMm = 0.001;

// Appends bytes to buffer 0 as a new buffer view (4-byte aligned, as glTF wants) and returns it.
int add_view(tinygltf::Model *m, const void *data, size_t size)
{
	std::vector<unsigned char> &buf = m->buffers[0].data;
	while (buf.size() % 4)
		buf.push_back(0);
	tinygltf::BufferView v;
	v.buffer = 0;
	v.byteOffset = buf.size();
	v.byteLength = size;
	const auto *p = static_cast<const unsigned char *>(data);
	buf.insert(buf.end(), p, p + size);
	m->bufferViews.push_back(v);
	return int(m->bufferViews.size() - 1);
}

// An accessor without a buffer view: KHR_draco_mesh_compression fills it when decoding.
int add_accessor(tinygltf::Model *m, int component, int type, size_t count, bool normalized,
		 std::vector<double> min = {}, std::vector<double> max = {})
{
	tinygltf::Accessor a;
	a.componentType = component;
	a.type = type;
	a.count = count;
	a.normalized = normalized;
	a.minValues = std::move(min);
	a.maxValues = std::move(max);
	m->accessors.push_back(a);
	return int(m->accessors.size() - 1);
}

// Keeps the encoded image bytes (PNG/JPEG) instead of decoding them with stb: OpenCV decodes.
bool keep_image_bytes(tinygltf::Image *image, const int, std::string *, std::string *, int, int,
		      const unsigned char *bytes, int size, void *)
{
	image->image.assign(bytes, bytes + size);
	image->as_is = true;
	return true;
}

int int_member(const tinygltf::Value &obj, const char *key)
{
	if (!obj.IsObject() || !obj.Has(key) || !obj.Get(key).IsNumber())
		return -1;
	return int(obj.Get(key).GetNumberAsInt());
}

uint32_t le32(const unsigned char *p)
{
	return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

void put_le32(std::string *s, uint32_t v)
{
	for (int k = 0; k < 4; ++k)
		s->push_back(char((v >> (8 * k)) & 0xff));
}

// tinygltf 2.7.0 built without Draco refuses an indices accessor without a bufferView, which is
// exactly what KHR_draco_mesh_compression prescribes. The indices come from the Draco bitstream
// anyway, so a copy of the glb with "indices" dropped from Draco primitives is what it parses.
Status drop_draco_indices(const unsigned char *data, size_t size, std::string *ret_glb)
{
	if (size < 20 || std::memcmp(data, "glTF", 4) != 0 || le32(data + 4) != 2)
		return Status::error(-EINVAL, "not a glTF 2.0 binary (no 'glTF' version 2 header)");
	const size_t total = le32(data + 8), json_len = le32(data + 12);
	if (total > size || total < 20 || json_len > total - 20 || le32(data + 16) != 0x4E4F534A)
		return Status::error(-EINVAL, "glb: header or JSON chunk length out of bounds");
	nlohmann::json j = nlohmann::json::parse(data + 20, data + 20 + json_len, nullptr, false);
	if (j.is_discarded() || !j.is_object())
		return Status::error(-EINVAL, "glb: the JSON chunk is not a JSON object");
	if (j.contains("meshes") && j["meshes"].is_array())
		for (nlohmann::json &m : j["meshes"])
			if (m.is_object() && m.contains("primitives") && m["primitives"].is_array())
				for (nlohmann::json &p : m["primitives"])
					if (p.is_object() && p.contains("extensions") && p["extensions"].is_object() &&
					    p["extensions"].contains(kDraco))
						p.erase("indices");
	std::string text = j.dump();
	while (text.size() % 4)
		text.push_back(' ');
	const size_t rest = total - 20 - json_len; // the BIN chunk and anything after, as it was
	std::string out;
	out.reserve(20 + text.size() + rest);
	out.append("glTF", 4);
	put_le32(&out, 2);
	put_le32(&out, uint32_t(20 + text.size() + rest));
	put_le32(&out, uint32_t(text.size()));
	put_le32(&out, 0x4E4F534A);
	out += text;
	out.append(reinterpret_cast<const char *>(data) + 20 + json_len, rest);
	*ret_glb = std::move(out);
	return {};
}

} // namespace

Status encode_glb(const recon::Mesh &mesh_mm, const DracoOptions &options, std::string *ret_bytes)
{
	Status s = check_mesh(mesh_mm);
	if (!s.ok())
		return s;
	recon::Mesh mesh = mesh_mm; // metres; the texture Mat is shared, not copied
	std::vector<double> lo(3, DBL_MAX), hi(3, -DBL_MAX);
	for (cv::Point3f &p : mesh.positions) {
		p *= float(kMetresPerMm);
		const double v[3] = {p.x, p.y, p.z};
		for (int k = 0; k < 3; ++k) {
			lo[size_t(k)] = std::min(lo[size_t(k)], v[k]);
			hi[size_t(k)] = std::max(hi[size_t(k)], v[k]);
		}
	}
	const bool textured = !mesh.texture.empty() && !mesh.uvs.empty();
	if (!textured)
		mesh.uvs.clear();
	std::vector<char> drc;
	DracoAttributeIds ids;
	s = encode_draco_ids(mesh, options, &drc, &ids);
	if (!s.ok())
		return s;

	tinygltf::Model m;
	m.asset.version = "2.0";
	m.asset.generator = "facescan";
	m.extensionsUsed = {kDraco};
	m.extensionsRequired = {kDraco};
	m.buffers.resize(1);
	const int drc_view = add_view(&m, drc.data(), drc.size());

	tinygltf::Primitive prim;
	prim.mode = TINYGLTF_MODE_TRIANGLES;
	tinygltf::Value::Object draco_attrs;
	const size_t n = mesh.positions.size();
	prim.attributes["POSITION"] =
		add_accessor(&m, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n, false, lo, hi);
	draco_attrs["POSITION"] = tinygltf::Value(ids.position);
	if (ids.uv >= 0) {
		prim.attributes["TEXCOORD_0"] =
			add_accessor(&m, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, n, false);
		draco_attrs["TEXCOORD_0"] = tinygltf::Value(ids.uv);
	}
	if (ids.normal >= 0) {
		prim.attributes["NORMAL"] = add_accessor(&m, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n, false);
		draco_attrs["NORMAL"] = tinygltf::Value(ids.normal);
	}
	if (ids.colour >= 0) {
		prim.attributes["COLOR_0"] =
			add_accessor(&m, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC3, n, true);
		draco_attrs["COLOR_0"] = tinygltf::Value(ids.colour);
	}
	prim.indices = add_accessor(&m, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
				    mesh.triangles.size() * 3, false);
	tinygltf::Value::Object ext;
	ext["bufferView"] = tinygltf::Value(drc_view);
	ext["attributes"] = tinygltf::Value(draco_attrs);
	prim.extensions[kDraco] = tinygltf::Value(ext);

	tinygltf::Material mat;
	mat.name = "face";
	mat.pbrMetallicRoughness.metallicFactor = 0;
	mat.pbrMetallicRoughness.roughnessFactor = 1;
	mat.doubleSided = true; // an open face surface: its back is seen from behind
	if (textured) {
		std::vector<unsigned char> png;
		if (!cv::imencode(".png", mesh.texture, png))
			return Status::error(-EIO, "texture: PNG encoding failed");
		tinygltf::Image img;
		img.name = "texture";
		img.mimeType = "image/png";
		img.bufferView = add_view(&m, png.data(), png.size());
		m.images.push_back(img);
		tinygltf::Sampler smp;
		smp.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
		smp.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
		smp.wrapS = smp.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
		m.samplers.push_back(smp);
		tinygltf::Texture tex;
		tex.source = 0;
		tex.sampler = 0;
		m.textures.push_back(tex);
		mat.pbrMetallicRoughness.baseColorTexture.index = 0;
	}
	m.materials.push_back(mat);
	prim.material = 0;

	tinygltf::Mesh gm;
	gm.name = "face";
	gm.primitives.push_back(prim);
	m.meshes.push_back(gm);
	tinygltf::Node node;
	node.mesh = 0;
	node.name = "face";
	m.nodes.push_back(node);
	tinygltf::Scene scene;
	scene.nodes = {0};
	m.scenes.push_back(scene);
	m.defaultScene = 0;

	tinygltf::TinyGLTF io;
	std::ostringstream out;
	if (!io.WriteGltfSceneToStream(&m, out, false, true))
		return Status::error(-EIO, "glTF: tinygltf could not write the model");
	*ret_bytes = out.str();
	return {};
}

Status decode_glb(const void *data, size_t size, recon::Mesh *ret_mesh)
{
	tinygltf::TinyGLTF io;
	io.SetImageLoader(keep_image_bytes, nullptr);
	tinygltf::Model m;
	std::string err, warn, glb;
	Status s = drop_draco_indices(static_cast<const unsigned char *>(data), size, &glb);
	if (!s.ok())
		return s;
	if (!io.LoadBinaryFromMemory(&m, &err, &warn, reinterpret_cast<const unsigned char *>(glb.data()),
				     unsigned(glb.size())))
		return Status::error(-EINVAL, "not a readable glb: " + (err.empty() ? warn : err));
	if (m.meshes.size() != 1 || m.meshes[0].primitives.size() != 1)
		return Status::error(-EINVAL, "glb: expected one mesh with one primitive, found " +
						      std::to_string(m.meshes.size()) + " meshes");
	const tinygltf::Primitive &prim = m.meshes[0].primitives[0];
	auto ext = prim.extensions.find(kDraco);
	if (ext == prim.extensions.end())
		return Status::error(-EINVAL, "glb: the primitive is not KHR_draco_mesh_compression "
					      "(only Draco-compressed glb is read)");
	const int view = int_member(ext->second, "bufferView");
	if (view < 0 || size_t(view) >= m.bufferViews.size())
		return Status::error(-EINVAL, "glb: Draco extension without a valid bufferView");
	const tinygltf::BufferView &bv = m.bufferViews[size_t(view)];
	if (bv.buffer < 0 || size_t(bv.buffer) >= m.buffers.size() ||
	    bv.byteOffset + bv.byteLength > m.buffers[size_t(bv.buffer)].data.size())
		return Status::error(-EINVAL, "glb: Draco bufferView outside its buffer");
	DracoAttributeIds ids;
	if (ext->second.Has("attributes")) {
		const tinygltf::Value &a = ext->second.Get("attributes");
		ids.position = int_member(a, "POSITION");
		ids.uv = int_member(a, "TEXCOORD_0");
		ids.normal = int_member(a, "NORMAL");
		ids.colour = int_member(a, "COLOR_0");
	}
	if (ids.position < 0)
		return Status::error(-EINVAL, "glb: Draco extension names no POSITION attribute");
	recon::Mesh mesh;
	s = decode_draco_ids(m.buffers[size_t(bv.buffer)].data.data() + bv.byteOffset, bv.byteLength,
				    &ids, &mesh);
	if (!s.ok())
		return Status::error(s.code(), "glb: " + s.message());
	for (cv::Point3f &p : mesh.positions)
		p *= float(1.0 / kMetresPerMm);

	if (prim.material >= 0 && size_t(prim.material) < m.materials.size()) {
		const int t = m.materials[size_t(prim.material)].pbrMetallicRoughness.baseColorTexture.index;
		if (t >= 0 && size_t(t) < m.textures.size()) {
			const int src = m.textures[size_t(t)].source;
			if (src >= 0 && size_t(src) < m.images.size() && !m.images[size_t(src)].image.empty()) {
				mesh.texture = cv::imdecode(m.images[size_t(src)].image, cv::IMREAD_COLOR);
				if (mesh.texture.empty())
					return Status::error(-EINVAL, "glb: the embedded texture is not a readable image");
			}
		}
	}
	*ret_mesh = std::move(mesh);
	return {};
}

Status write_glb(const std::string &path, const recon::Mesh &mesh, const DracoOptions &options)
{
	std::string bytes;
	Status s = encode_glb(mesh, options, &bytes);
	if (!s.ok())
		return Status::error(s.code(), path + ": " + s.message());
	return write_file_atomic(path, bytes.data(), bytes.size());
}

Status read_glb(const std::string &path, recon::Mesh *ret_mesh)
{
	std::string bytes;
	Status s = read_file_bytes(path, &bytes);
	if (!s.ok())
		return s;
	s = decode_glb(bytes.data(), bytes.size(), ret_mesh);
	if (!s.ok())
		return Status::error(s.code(), path + ": " + s.message());
	return {};
}

} // namespace facescan::mesh_io
