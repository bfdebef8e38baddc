// Internal to host/mesh_io: the one way to include tinygltf (Debian's libtinygltf-dev header).
// We compile its implementation ourselves (tinygltf_impl.cpp, the route README.Debian names):
// Debian's libtinygltf.so disagrees with its own header about the layout of the model structs
// (a Sampler from the library crashed our destructor). Images are encoded/decoded by OpenCV,
// so tinygltf's stb paths are compiled out.
#pragma once

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>
