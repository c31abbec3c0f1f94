#include "version.h"

namespace coherent {

const char* version_string() { return COHERENT_VERSION; }

const char* build_info() {
    return "coherent " COHERENT_VERSION ", " __VERSION__
#if defined(__AVX512F__)
           ", AVX-512"
#elif defined(__AVX2__)
           ", AVX2"
#endif
#if defined(NDEBUG)
           ", release";
#else
           ", debug";
#endif
}

}  // namespace coherent
