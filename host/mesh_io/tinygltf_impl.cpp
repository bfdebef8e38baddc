// tinygltf's implementation, compiled once with the settings of mesh_io/tinygltf.hpp.
#define TINYGLTF_IMPLEMENTATION
#include "mesh_io/tinygltf.hpp"
