// A shipped parameter set by name, and the paper's Fig. 6 test for 0.1 s.
#include <cstdio>
#include <granflow/elementtest/run.hpp>

int main() {
  const granflow::io::ParameterSet set = granflow::io::load_parameter_set("element_test");
  granflow::elementtest::ElementTest test;  // undrained simple shear, e0 = 0.99, 500 Pa
  test.programme.duration = 0.1;
  const granflow::elementtest::ResultTable r = granflow::elementtest::run_element_test(test, set);
  std::printf("rows %zu, tau at 0.1 s: %.6g Pa\n", r.rows(), r.column("tau").back());
  return r.rows() == 201 ? 0 : 1;
}
