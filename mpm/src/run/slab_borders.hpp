// Borders of a scene split into slabs along x (docs/mpm_slabs.md), shared by the CPU twin's
// split (cpu_slabs.hpp) and the GPUs' (cuda_slabs.cuh).
#pragma once

#include <algorithm>
#include <vector>

namespace granflow::mpm {

// Borders that give each of n slabs about the same number of points (counts: points per
// stencil-base column), every slab at least min_width columns wide.
inline std::vector<int> balanced_borders(const std::vector<long>& counts, int n, int min_width) {
  const int cols = static_cast<int>(counts.size());
  std::vector<long> below(cols + 1, 0);  // points in columns < c
  for (int c = 0; c < cols; ++c) below[c + 1] = below[c] + counts[c];
  std::vector<int> b(n + 1, 0);
  b[n] = cols;
  for (int s = 1; s < n; ++s) {
    const double target = double(below[cols]) * s / n;
    int x = static_cast<int>(std::lower_bound(below.begin(), below.end(), target) - below.begin());
    x = std::max(x, b[s - 1] + min_width);
    x = std::min(x, cols - (n - s) * min_width);
    b[s] = x;
  }
  return b;
}

// The slab that owns node column `column` (borders as balanced_borders gives them).
inline int slab_of_column(const std::vector<int>& borders, int column) {
  return static_cast<int>(std::upper_bound(borders.begin() + 1, borders.end() - 1, column) - borders.begin()) - 1;
}

}  // namespace granflow::mpm
