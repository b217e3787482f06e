// Borders of a scene split into slabs along x (docs/mpm_slabs.md), shared by the CPU twin's
// split (cpu_slabs.hpp) and the GPUs' (cuda_slabs.cuh).
#pragma once

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include <granflow/mpm/runner.hpp>

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

// Slabs for points whose stencils start in node columns `col` (of `cols`): the borders balanced
// by point count (a re-partition counted in the report where they moved) and, per slab, its
// points in ascending order.
inline std::vector<std::vector<long>> assign_slabs(const std::vector<int>& col, int cols, int slabs, int K,
                                                   SlabReport& report) {
  std::vector<long> counts(cols, 0);
  for (int c : col) ++counts[c];
  const std::vector<int> b = balanced_borders(counts, slabs, K);
  if (!report.borders.empty() && b != report.borders) ++report.repartitions;
  report.borders = b;
  std::vector<std::vector<long>> which(slabs);
  for (size_t p = 0; p < col.size(); ++p) which[slab_of_column(b, col[p])].push_back(static_cast<long>(p));
  return which;
}

// What a split refuses to set up (std::invalid_argument): an ensemble, and slabs narrower than
// one stencil of K node columns.
inline void check_split(const SceneSetup& su, const SlabOptions& o, int K) {
  if (su.members > 1)
    throw std::invalid_argument("slabs: an ensemble is not split (--devices spreads its members over GPUs)");
  if (o.slabs < 1 || su.nodes[0] < K * o.slabs)
    throw std::invalid_argument("slabs: " + std::to_string(o.slabs) + " slabs of at least " + std::to_string(K) +
                                " node columns each (one stencil) do not fit the grid's " +
                                std::to_string(su.nodes[0]) + " columns along x");
}

// The re-partitioning rule (SlabOptions): after each step, given the fullest slab's points,
// whether to move the borders now; keeps the report's largest imbalance and requests.
struct Repartitioning {
  SlabOptions opt;
  long steps = 0, since = 0;
  bool after_step(long most, long total, int slabs, SlabReport& report) {
    ++steps;
    ++since;
    const double imbalance = total > 0 ? double(most) * double(slabs) / double(total) : 1.0;
    report.max_imbalance = std::max(report.max_imbalance, imbalance);
    const bool every = opt.every > 0 && steps % opt.every == 0;
    if (!every && !(imbalance > opt.imbalance && since >= opt.min_steps)) return false;
    ++report.checks;
    since = 0;
    return true;
  }
};

}  // namespace granflow::mpm
