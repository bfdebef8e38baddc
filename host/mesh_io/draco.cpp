// Draco encode/decode of recon::Mesh. Positions are float mm; the quantisation step is the
// bounding box's longest side / (2^position_bits - 1).
#include "mesh_io/draco_ids.hpp"
#include "mesh_io/mesh_check.hpp"
#include "mesh_io/mesh_io.hpp"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <cmath>
#include <memory>

namespace facescan::mesh_io {

double draco_position_step(double extent, int position_bits)
{
	return extent / (std::pow(2.0, position_bits) - 1.0);
}

namespace {

template <typename T>
int add_attribute(draco::Mesh *dm, draco::GeometryAttribute::Type type, int components,
		  draco::DataType data_type, bool normalized, const std::vector<T> &values)
{
	draco::GeometryAttribute ga;
	ga.Init(type, nullptr, uint8_t(components), data_type, normalized,
		int64_t(sizeof(T)), 0);
	const int id = dm->AddAttribute(ga, true, uint32_t(values.size()));
	draco::PointAttribute *pa = dm->attribute(id);
	for (size_t i = 0; i < values.size(); ++i)
		pa->SetAttributeValue(draco::AttributeValueIndex(uint32_t(i)), &values[i]);
	return id;
}

} // namespace

Status encode_draco(const recon::Mesh &mesh, const DracoOptions &options, std::vector<char> *ret_bytes)
{
	DracoAttributeIds ids;
	return encode_draco_ids(mesh, options, ret_bytes, &ids);
}

Status encode_draco_ids(const recon::Mesh &mesh, const DracoOptions &options, std::vector<char> *ret_bytes,
			DracoAttributeIds *ret_ids)
{
	Status s = check_mesh(mesh);
	if (!s.ok())
		return s;
	if (mesh.triangles.empty())
		return Status::error(-EINVAL, "mesh has no triangles");
	const size_t n = mesh.positions.size();
	draco::Mesh dm;
	dm.set_num_points(uint32_t(n));
	DracoAttributeIds ids;
	ids.position = add_attribute(&dm, draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32, false,
				     mesh.positions);
	if (!mesh.uvs.empty())
		ids.uv = add_attribute(&dm, draco::GeometryAttribute::TEX_COORD, 2, draco::DT_FLOAT32, false,
				       mesh.uvs);
	if (options.normals && !mesh.normals.empty())
		ids.normal = add_attribute(&dm, draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32, false,
					   mesh.normals);
	if (!mesh.colours.empty()) {
		// recon keeps OpenCV's BGR; files carry RGB.
		std::vector<cv::Vec3b> rgb(mesh.colours.size());
		for (size_t i = 0; i < rgb.size(); ++i)
			rgb[i] = cv::Vec3b(mesh.colours[i][2], mesh.colours[i][1], mesh.colours[i][0]);
		ids.colour = add_attribute(&dm, draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8, true, rgb);
	}
	for (const cv::Vec3i &t : mesh.triangles) {
		draco::Mesh::Face f;
		for (int k = 0; k < 3; ++k)
			f[k] = draco::PointIndex(uint32_t(t[k]));
		dm.AddFace(f);
	}

	draco::Encoder enc;
	enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.position_bits);
	enc.SetAttributeQuantization(draco::GeometryAttribute::TEX_COORD, options.uv_bits);
	enc.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, options.normal_bits);
	enc.SetAttributeQuantization(draco::GeometryAttribute::COLOR, options.colour_bits);
	enc.SetSpeedOptions(options.speed, options.speed);
	draco::EncoderBuffer buf;
	const draco::Status ds = enc.EncodeMeshToBuffer(dm, &buf);
	if (!ds.ok())
		return Status::error(-EIO, std::string("draco encode: ") + ds.error_msg());
	ret_bytes->assign(buf.data(), buf.data() + buf.size());
	// The encoder keeps attribute ids (they are in the bitstream as unique ids).
	for (int *id : {&ids.position, &ids.uv, &ids.normal, &ids.colour})
		if (*id >= 0)
			*id = int(dm.attribute(*id)->unique_id());
	*ret_ids = ids;
	return {};
}

Status decode_draco(const void *data, size_t size, recon::Mesh *ret_mesh)
{
	return decode_draco_ids(data, size, nullptr, ret_mesh);
}

Status decode_draco_ids(const void *data, size_t size, const DracoAttributeIds *ids, recon::Mesh *ret_mesh)
{
	draco::DecoderBuffer db;
	db.Init(static_cast<const char *>(data), size);
	auto type = draco::Decoder::GetEncodedGeometryType(&db);
	if (!type.ok())
		return Status::error(-EINVAL, std::string("not a Draco file: ") + type.status().error_msg());
	if (type.value() != draco::TRIANGULAR_MESH)
		return Status::error(-EINVAL, "Draco file holds a point cloud, not a mesh");
	draco::Decoder dec;
	auto decoded = dec.DecodeMeshFromBuffer(&db);
	if (!decoded.ok())
		return Status::error(-EINVAL, std::string("draco decode: ") + decoded.status().error_msg());
	const std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();

	recon::Mesh mesh;
	const uint32_t n = dm->num_points();
	// glTF names attributes by unique id; a plain .drc by type.
	auto find = [&](draco::GeometryAttribute::Type type, int unique_id) -> const draco::PointAttribute * {
		if (!ids)
			return dm->GetNamedAttribute(type);
		return unique_id < 0 ? nullptr : dm->GetAttributeByUniqueId(uint32_t(unique_id));
	};
	const draco::PointAttribute *pos = find(draco::GeometryAttribute::POSITION, ids ? ids->position : -1);
	if (!pos || pos->num_components() != 3)
		return Status::error(-EINVAL, "Draco mesh has no 3-component positions");
	const draco::PointAttribute *uv = find(draco::GeometryAttribute::TEX_COORD, ids ? ids->uv : -1);
	const draco::PointAttribute *nor = find(draco::GeometryAttribute::NORMAL, ids ? ids->normal : -1);
	const draco::PointAttribute *col = find(draco::GeometryAttribute::COLOR, ids ? ids->colour : -1);
	if ((uv && uv->num_components() != 2) || (nor && nor->num_components() != 3) ||
	    (col && col->num_components() < 3))
		return Status::error(-EINVAL, "Draco mesh has attributes of the wrong size");
	mesh.positions.resize(n);
	if (uv)
		mesh.uvs.resize(n);
	if (nor)
		mesh.normals.resize(n);
	if (col)
		mesh.colours.resize(n);
	for (uint32_t i = 0; i < n; ++i) {
		const draco::PointIndex p(i);
		float v[3] = {0, 0, 0};
		pos->ConvertValue<float>(pos->mapped_index(p), 3, v);
		mesh.positions[i] = cv::Point3f(v[0], v[1], v[2]);
		if (uv) {
			uv->ConvertValue<float>(uv->mapped_index(p), 2, v);
			mesh.uvs[i] = cv::Point2f(v[0], v[1]);
		}
		if (nor) {
			nor->ConvertValue<float>(nor->mapped_index(p), 3, v);
			mesh.normals[i] = cv::Point3f(v[0], v[1], v[2]);
		}
		if (col) {
			uint8_t c[3] = {0, 0, 0};
			col->ConvertValue<uint8_t>(col->mapped_index(p), 3, c);
			mesh.colours[i] = cv::Vec3b(c[2], c[1], c[0]);
		}
	}
	mesh.triangles.resize(dm->num_faces());
	for (uint32_t f = 0; f < dm->num_faces(); ++f) {
		const draco::Mesh::Face &face = dm->face(draco::FaceIndex(f));
		mesh.triangles[f] = cv::Vec3i(int(face[0].value()), int(face[1].value()), int(face[2].value()));
	}
	*ret_mesh = std::move(mesh);
	return {};
}

} // namespace facescan::mesh_io
