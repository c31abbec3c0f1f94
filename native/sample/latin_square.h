// Random partitions of an n x n pixel block into n Latin-hypercube (n-rooks)
// subsets, as ICPT needs them: every subset holds exactly one pixel of each
// row and of each column. Such a partition is a Latin square: cell (r, c)
// carries the index of its subset, and each index appears once per row and
// once per column.
//
// The partition is a pure function of a 64-bit hash, so a block's pattern for
// a sample is drawn without state. For n <= kEnumeratedOrder every Latin
// square is enumerated once and the hash picks one uniformly (576 squares for
// n = 4: every partition, every assignment of subsets to sequences). Larger
// blocks use a random isotope of the cyclic square, L(r, c) = (P[r] + Q[c]) mod n
// with random permutations P and Q: still one pixel per row and column per
// subset, re-randomised per hash, though not uniform over all Latin squares.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace coherent {

class LatinSquares {
public:
    static constexpr uint32_t kEnumeratedOrder = 4;
    static constexpr uint32_t kMaxOrder = 16;

    // 1 <= n <= kMaxOrder (clamped).
    explicit LatinSquares(uint32_t n);

    uint32_t order() const { return n_; }
    // Number of distinct squares the hash chooses from (0 = isotope mode).
    size_t enumerated_count() const { return n_ ? squares_.size() / (size_t(n_) * n_) : 0; }

    // Subset index in [0, n) of cell (row, col) of the square chosen by `h`.
    uint32_t subset(uint64_t h, uint32_t row, uint32_t col) const;

private:
    uint32_t n_;
    std::vector<uint8_t> squares_;  // enumerated squares, row-major, n*n bytes each
};

// The shared table for one order (built on first use, thread-safe).
const LatinSquares& latin_squares(uint32_t n);

}  // namespace coherent
