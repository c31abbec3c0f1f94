// std::allocator replacement for large arrays read at random (image
// textures): blocks of 2 MiB and more start on a 2 MiB boundary and ask the
// kernel for transparent huge pages. A texture lookup lands anywhere in tens
// of megabytes of texels; with 4 KiB pages nearly every lookup also misses
// the TLB (2,048 entries cover 8 MiB), and the page walk costs as much as
// the texel's own cache miss. Debian's kernels default to THP "madvise",
// which gives huge pages only to memory that asks for them. Smaller blocks
// and kernels without THP get ordinary memory; the contents are the same.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace coherent {

template <class T>
struct HugePageAllocator {
    using value_type = T;
    static constexpr size_t kHugePage = size_t(2) << 20;

    HugePageAllocator() = default;
    template <class U>
    HugePageAllocator(const HugePageAllocator<U>&) {}

    T* allocate(size_t n) {
        const size_t bytes = n * sizeof(T);
        void* p = nullptr;
        if (bytes >= kHugePage) {
            p = std::aligned_alloc(kHugePage, (bytes + kHugePage - 1) / kHugePage * kHugePage);
#if defined(__linux__) && defined(MADV_HUGEPAGE)
            if (p) madvise(p, bytes, MADV_HUGEPAGE);  // advice only: failure leaves ordinary pages
#endif
        } else {
            p = std::malloc(bytes ? bytes : 1);
        }
        if (!p) throw std::bad_alloc();
        return static_cast<T*>(p);
    }
    void deallocate(T* p, size_t) { std::free(p); }

    template <class U>
    bool operator==(const HugePageAllocator<U>&) const { return true; }
    template <class U>
    bool operator!=(const HugePageAllocator<U>&) const { return false; }
};

}  // namespace coherent
