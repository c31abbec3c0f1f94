#include "latin_square.h"

#include <algorithm>
#include <array>
#include <mutex>

#include "../core/random.h"

namespace coherent {

namespace {

// Depth-first enumeration: fill cells in row-major order with every symbol
// not yet used in the cell's row or column.
void enumerate(uint32_t n, uint32_t cell, std::vector<uint8_t>& square, std::vector<uint8_t>& out) {
    if (cell == n * n) {
        out.insert(out.end(), square.begin(), square.end());
        return;
    }
    const uint32_t r = cell / n, c = cell % n;
    for (uint8_t s = 0; s < n; ++s) {
        bool used = false;
        for (uint32_t k = 0; k < c && !used; ++k) used = square[r * n + k] == s;
        for (uint32_t k = 0; k < r && !used; ++k) used = square[k * n + c] == s;
        if (used) continue;
        square[cell] = s;
        enumerate(n, cell + 1, square, out);
    }
}

// Element i of a random permutation of [0, n), Fisher-Yates from `seed`.
uint32_t permuted(uint64_t seed, uint32_t n, uint32_t i) {
    std::array<uint8_t, LatinSquares::kMaxOrder> p{};
    for (uint32_t k = 0; k < n; ++k) p[k] = uint8_t(k);
    Pcg32 rng(seed);
    for (uint32_t k = n - 1; k > 0; --k) std::swap(p[k], p[rng.next_u32() % (k + 1)]);
    return p[i];
}

}  // namespace

LatinSquares::LatinSquares(uint32_t n) : n_(std::clamp<uint32_t>(n, 1, kMaxOrder)) {
    if (n_ <= kEnumeratedOrder) {
        std::vector<uint8_t> square(size_t(n_) * n_, 0);
        enumerate(n_, 0, square, squares_);
    }
}

uint32_t LatinSquares::subset(uint64_t h, uint32_t row, uint32_t col) const {
    if (!squares_.empty()) {
        const size_t count = squares_.size() / (size_t(n_) * n_);
        // Multiply-shift maps the top 32 bits onto [0, count) without modulo bias worth noting (count <= 576).
        const size_t k = size_t(((h >> 32) * uint64_t(count)) >> 32);
        return squares_[k * n_ * n_ + row * n_ + col];
    }
    const uint32_t pr = permuted(mix64(h ^ 0x243f6a8885a308d3ull), n_, row);
    const uint32_t qc = permuted(mix64(h ^ 0x13198a2e03707344ull), n_, col);
    return (pr + qc) % n_;
}

const LatinSquares& latin_squares(uint32_t n) {
    static std::array<std::once_flag, LatinSquares::kMaxOrder + 1> once;
    static std::array<const LatinSquares*, LatinSquares::kMaxOrder + 1> table{};
    n = std::clamp<uint32_t>(n, 1, LatinSquares::kMaxOrder);
    // Built once per order and kept for the process lifetime (a few KB).
    std::call_once(once[n], [n] { table[n] = new LatinSquares(n); });
    return *table[n];
}

}  // namespace coherent
