// OBJ (+ MTL) and binary STL through assimp's importers and exporters. assimp's exporters write
// through an IOSystem; ours collects the files in memory so that each lands with
// write_file_atomic() (a half-written OBJ is never seen) and the names the OBJ gives its MTL
// stay those of the final paths.
#include "mesh_io/mesh_check.hpp"
#include "mesh_io/mesh_io.hpp"

#include "capture/capture_set.hpp"

#include <assimp/Exporter.hpp>
#include <assimp/IOStream.hpp>
#include <assimp/IOSystem.hpp>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <opencv2/imgcodecs.hpp>

#include <cstring>
#include <unistd.h>
#include <map>
#include <memory>

namespace facescan::mesh_io {

namespace {

using FileMap = std::map<std::string, std::string>;

class MemStream : public Assimp::IOStream {
public:
	explicit MemStream(std::string *data) : data_(data) {}
	size_t Read(void *, size_t, size_t) override { return 0; } // write-only
	size_t Write(const void *buf, size_t size, size_t count) override
	{
		const size_t n = size * count;
		if (pos_ + n > data_->size())
			data_->resize(pos_ + n);
		std::memcpy(&(*data_)[pos_], buf, n);
		pos_ += n;
		return count;
	}
	aiReturn Seek(size_t offset, aiOrigin origin) override
	{
		const size_t base = origin == aiOrigin_SET ? 0 : origin == aiOrigin_CUR ? pos_ : data_->size();
		if (base + offset > data_->size())
			return aiReturn_FAILURE;
		pos_ = base + offset;
		return aiReturn_SUCCESS;
	}
	size_t Tell() const override { return pos_; }
	size_t FileSize() const override { return data_->size(); }
	void Flush() override {}

private:
	std::string *data_;
	size_t pos_ = 0;
};

// Exporter side only: every Open() for writing gets an in-memory file; reading is refused.
class MemIOSystem : public Assimp::IOSystem {
public:
	explicit MemIOSystem(FileMap *files) : files_(files) {}
	bool Exists(const char *path) const override { return files_->count(path) != 0; }
	char getOsSeparator() const override { return '/'; }
	Assimp::IOStream *Open(const char *path, const char *mode) override
	{
		if (!mode || !std::strchr(mode, 'w'))
			return nullptr;
		std::string &f = (*files_)[path];
		f.clear();
		return new MemStream(&f);
	}
	void Close(Assimp::IOStream *stream) override { delete stream; }

private:
	FileMap *files_;
};

double file_scale(Units units) // file units per mm
{
	return units == Units::m ? 0.001 : 1.0;
}

std::string dir_of(const std::string &path)
{
	const size_t slash = path.rfind('/');
	return slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
}

std::string stem_of(const std::string &path)
{
	const size_t slash = path.rfind('/');
	const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
	const size_t dot = name.rfind('.');
	return dot == std::string::npos ? name : name.substr(0, dot);
}

// A one-mesh scene; the aiScene destructor frees everything allocated here.
std::unique_ptr<aiScene> make_scene(const recon::Mesh &mesh, Units units, bool with_uv_and_colour,
				    const std::string &texture_name)
{
	auto scene = std::make_unique<aiScene>();
	scene->mRootNode = new aiNode("face");
	scene->mRootNode->mNumMeshes = 1;
	scene->mRootNode->mMeshes = new unsigned[1]{0};
	scene->mNumMaterials = 1;
	scene->mMaterials = new aiMaterial *[1];
	aiMaterial *mat = new aiMaterial;
	scene->mMaterials[0] = mat;
	const aiString mat_name("face");
	mat->AddProperty(&mat_name, AI_MATKEY_NAME);
	const aiColor3D white(1, 1, 1);
	mat->AddProperty(&white, 1, AI_MATKEY_COLOR_DIFFUSE);
	if (!texture_name.empty()) {
		const aiString tex(texture_name);
		mat->AddProperty(&tex, AI_MATKEY_TEXTURE_DIFFUSE(0));
	}
	scene->mNumMeshes = 1;
	scene->mMeshes = new aiMesh *[1];
	aiMesh *am = new aiMesh;
	scene->mMeshes[0] = am;
	am->mMaterialIndex = 0;
	am->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
	const size_t n = mesh.positions.size();
	const float k = float(file_scale(units));
	am->mNumVertices = unsigned(n);
	am->mVertices = new aiVector3D[n];
	for (size_t i = 0; i < n; ++i)
		am->mVertices[i] = aiVector3D(mesh.positions[i].x * k, mesh.positions[i].y * k, mesh.positions[i].z * k);
	if (with_uv_and_colour && mesh.normals.size() == n) {
		am->mNormals = new aiVector3D[n];
		for (size_t i = 0; i < n; ++i)
			am->mNormals[i] = aiVector3D(mesh.normals[i].x, mesh.normals[i].y, mesh.normals[i].z);
	}
	if (with_uv_and_colour && mesh.uvs.size() == n) {
		am->mNumUVComponents[0] = 2;
		am->mTextureCoords[0] = new aiVector3D[n];
		for (size_t i = 0; i < n; ++i) // assimp and OBJ: v up; recon: v down
			am->mTextureCoords[0][i] = aiVector3D(mesh.uvs[i].x, 1.0f - mesh.uvs[i].y, 0);
	}
	if (with_uv_and_colour && mesh.colours.size() == n && mesh.uvs.empty()) {
		am->mColors[0] = new aiColor4D[n];
		for (size_t i = 0; i < n; ++i) // BGR → RGB
			am->mColors[0][i] = aiColor4D(mesh.colours[i][2] / 255.0f, mesh.colours[i][1] / 255.0f,
						      mesh.colours[i][0] / 255.0f, 1.0f);
	}
	am->mNumFaces = unsigned(mesh.triangles.size());
	am->mFaces = new aiFace[mesh.triangles.size()];
	for (size_t f = 0; f < mesh.triangles.size(); ++f) {
		am->mFaces[f].mNumIndices = 3;
		am->mFaces[f].mIndices = new unsigned[3];
		for (int c = 0; c < 3; ++c)
			am->mFaces[f].mIndices[c] = unsigned(mesh.triangles[f][c]);
	}
	return scene;
}

// Runs one of assimp's exporters into memory; returns the files it wrote by path.
Status export_scene(const aiScene &scene, const char *format, const std::string &path, FileMap *ret_files)
{
	Assimp::Exporter exporter;
	exporter.SetIOHandler(new MemIOSystem(ret_files)); // the exporter owns and deletes it
	if (exporter.Export(&scene, format, path) != aiReturn_SUCCESS)
		return Status::error(-EIO, path + ": assimp " + format + " export: " + exporter.GetErrorString());
	return {};
}

// Imports with assimp into one mesh (all meshes of the scene, transforms applied).
Status import_mesh(const std::string &path, Units units, unsigned extra_flags, bool is_stl,
		   recon::Mesh *ret_mesh, std::string *ret_texture_path)
{
	Assimp::Importer importer;
	if (is_stl) // STL repeats vertices per face with face normals: drop normals so they merge
		importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, aiComponent_NORMALS);
	const aiScene *scene = importer.ReadFile(
		path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices |
			      aiProcess_SortByPType | extra_flags);
	if (!scene || !scene->mRootNode)
		return Status::error(-EINVAL, path + ": not a readable mesh: " + importer.GetErrorString());
	recon::Mesh mesh;
	const float k = float(1.0 / file_scale(units));
	bool all_uv = true, all_normals = true;
	for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
		const aiMesh *am = scene->mMeshes[mi];
		all_uv = all_uv && am->mTextureCoords[0];
		all_normals = all_normals && am->mNormals;
	}
	for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
		const aiMesh *am = scene->mMeshes[mi];
		if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE))
			continue; // points and lines carry no surface
		const int base = int(mesh.positions.size());
		for (unsigned i = 0; i < am->mNumVertices; ++i) {
			const aiVector3D &v = am->mVertices[i];
			mesh.positions.emplace_back(v.x * k, v.y * k, v.z * k);
			if (all_uv)
				mesh.uvs.emplace_back(am->mTextureCoords[0][i].x, 1.0f - am->mTextureCoords[0][i].y);
			if (all_normals)
				mesh.normals.emplace_back(am->mNormals[i].x, am->mNormals[i].y, am->mNormals[i].z);
		}
		for (unsigned f = 0; f < am->mNumFaces; ++f) {
			const aiFace &face = am->mFaces[f];
			if (face.mNumIndices != 3)
				continue;
			mesh.triangles.emplace_back(base + int(face.mIndices[0]), base + int(face.mIndices[1]),
						    base + int(face.mIndices[2]));
		}
	}
	if (mesh.triangles.empty())
		return Status::error(-EINVAL, path + ": no triangles");
	if (ret_texture_path) {
		ret_texture_path->clear();
		aiString tex;
		for (unsigned i = 0; i < scene->mNumMaterials && ret_texture_path->empty(); ++i)
			if (scene->mMaterials[i]->GetTexture(aiTextureType_DIFFUSE, 0, &tex) == aiReturn_SUCCESS &&
			    tex.length > 0)
				*ret_texture_path = tex.C_Str();
	}
	*ret_mesh = std::move(mesh);
	return {};
}

} // namespace

Status encode_stl(const recon::Mesh &mesh, Units units, std::string *ret_bytes)
{
	Status s = check_mesh(mesh);
	if (!s.ok() || mesh.triangles.empty())
		return Status::error(-EINVAL, s.ok() ? "mesh has no triangles" : s.message());
	const std::unique_ptr<aiScene> scene = make_scene(mesh, units, false, "");
	FileMap files;
	const std::string name = "/mesh.stl"; // a name only: the file stays in memory
	s = export_scene(*scene, "stlb", name, &files);
	if (!s.ok())
		return s;
	auto f = files.find(name);
	if (f == files.end() || files.size() != 1)
		return Status::error(-EIO, "assimp wrote an unexpected set of files");
	*ret_bytes = std::move(f->second);
	return {};
}

Status write_stl(const std::string &path, const recon::Mesh &mesh, Units units)
{
	std::string bytes;
	Status s = encode_stl(mesh, units, &bytes);
	if (!s.ok())
		return Status::error(s.code(), path + ": " + s.message());
	return write_file_atomic(path, bytes.data(), bytes.size());
}

Status read_stl(const std::string &path, Units units, recon::Mesh *ret_mesh)
{
	return import_mesh(path, units, aiProcess_RemoveComponent, true, ret_mesh, nullptr);
}

Status write_obj(const std::string &path, const recon::Mesh &mesh, Units units, const std::string &texture_name,
		 bool write_texture, ObjFiles *ret_files)
{
	Status s = check_mesh(mesh);
	if (!s.ok() || mesh.triangles.empty())
		return Status::error(-EINVAL, path + ": " + (s.ok() ? "mesh has no triangles" : s.message()));
	const bool textured = !mesh.texture.empty() && !mesh.uvs.empty();
	if (textured && (texture_name.empty() || texture_name.find('/') != std::string::npos))
		return Status::error(-EINVAL, path + ": texture name must be a plain file name");
	const std::unique_ptr<aiScene> scene = make_scene(mesh, units, true, textured ? texture_name : "");
	FileMap files;
	s = export_scene(*scene, "obj", path, &files);
	if (!s.ok())
		return s;
	const std::string mtl = dir_of(path) + stem_of(path) + ".mtl";
	if (files.size() != 2 || !files.count(path) || !files.count(mtl))
		return Status::error(-EIO, path + ": assimp wrote an unexpected set of files");
	ObjFiles written;
	if (textured) {
		written.texture = dir_of(path) + texture_name;
		if (write_texture) {
			std::vector<unsigned char> png;
			if (!cv::imencode(".png", mesh.texture, png))
				return Status::error(-EIO, written.texture + ": PNG encoding failed");
			s = write_file_atomic(written.texture, png.data(), png.size());
			if (!s.ok())
				return s;
		}
	}
	// The MTL before the OBJ: whoever opens the OBJ finds its material complete.
	s = write_file_atomic(mtl, files[mtl].data(), files[mtl].size());
	if (!s.ok())
		return s;
	s = write_file_atomic(path, files[path].data(), files[path].size());
	if (!s.ok())
		return s;
	written.obj = path;
	written.mtl = mtl;
	if (ret_files)
		*ret_files = written;
	return {};
}

Status read_obj(const std::string &path, Units units, recon::Mesh *ret_mesh)
{
	recon::Mesh mesh;
	std::string tex;
	Status s = import_mesh(path, units, 0, false, &mesh, &tex);
	if (!s.ok())
		return s;
	if (!tex.empty() && !mesh.uvs.empty()) {
		const std::string tex_path = tex[0] == '/' ? tex : dir_of(path) + tex;
		// imread would log a warning for a missing file and wait on a FIFO.
		if (access(tex_path.c_str(), R_OK) == 0 && check_regular_input(tex_path).ok())
			mesh.texture = cv::imread(tex_path, cv::IMREAD_COLOR);
		if (mesh.texture.empty())
			return Status::error(-EINVAL, path + ": its texture '" + tex_path + "' is missing or unreadable");
	}
	*ret_mesh = std::move(mesh);
	return {};
}

} // namespace facescan::mesh_io
