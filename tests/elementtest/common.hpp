#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <string>

#include <granflow/constitutive.hpp>
#include <granflow/elementtest/paper.hpp>
#include <granflow/elementtest/run.hpp>

#include <granflow/io/parameter_set.hpp>

namespace gt = granflow::elementtest;
using granflow::io::ParameterSet;

// Writes text to the test's temporary folder; returns the path.
inline std::string write(const std::string& name, const std::string& text) {
  const std::string p = ::testing::TempDir() + "/" + name;
  std::ofstream(p) << text;
  return p;
}

inline ParameterSet pset(const std::string& name) { return granflow::io::load_parameter_set(name); }

inline double last(const gt::ResultTable& r, const std::string& c) { return r.column(c).back(); }

// Every row finite, T >= 0, e in (0, 2.97).
inline void expect_admissible(const gt::ResultTable& r) {
  ASSERT_GT(r.rows(), 0u);
  for (std::size_t i = 0; i < r.names.size(); ++i)
    for (double v : r.columns[i]) ASSERT_TRUE(std::isfinite(v)) << r.names[i];
  for (double T : r.column("T")) ASSERT_GE(T, 0.0);
  for (double e : r.column("e")) {
    ASSERT_GT(e, 0.0);
    ASSERT_LT(e, 2.97);
  }
}
