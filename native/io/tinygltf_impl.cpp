// tinygltf's implementation is compiled here, and only here.
#define TINYGLTF_IMPLEMENTATION
#include "tinygltf_config.h"
