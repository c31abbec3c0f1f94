#pragma once

namespace coherent {

// "MAJOR.MINOR.PATCH", from the CMake project version.
const char* version_string();
// Compiler and ISA the engine was built for, for bug reports and benchmarks.
const char* build_info();

}  // namespace coherent
