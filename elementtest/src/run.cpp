// run_element_test: checks the test, picks the model, and runs one Driver per rate programme
// (one per rate of a sweep). The driver itself: element_driver.hpp.
#include <time.h>

#include "element_driver.hpp"
#include "output_rows.hpp"

namespace granflow::elementtest {

namespace {

using namespace detail;

double cpu_now() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

template <class Model>
ResultTable run_model(const ElementTest& test, const typename Model::Params& p, const io::ParameterSet& set,
                      const ProgressCallback& progress) {
  ResultTable out;
  out.names = result_column_names();
  out.columns.assign(out.names.size(), {});
  const double c0 = cpu_now();
  const RateProgramme& g = test.programme;
  if (g.kind == ProgrammeKind::Data) {
    const DataSchedule d = data_schedule(g, test.initial.sigma_v0, test.file.empty() ? g.data_file : test.file);
    Driver<Model> drv(test, p, set);
    ElementState x = drv.initial_state();
    if (g.control == Control::Strain) x.eps_a = d.start;  // eps_a follows the column itself
    drv.run(x, d.segments, d.out_times, out, progress);
  } else if (g.kind != ProgrammeKind::Sweep) {
    const std::vector<Segment> segs = segments_of(g);
    if (segs.empty()) throw io::InputError(io::where(test.file) + "the rate programme has no time span");
    Driver<Model> drv(test, p, set);
    ElementState x = drv.initial_state();
    drv.run(x, segs, output_times(test.output, segs.front().t0, segs.back().t1), out, progress);
  } else {
    if (g.sweep_rates.empty()) throw io::InputError(io::where(test.file) + "the sweep has no rates");
    ResultTable one;
    one.names = out.names;
    std::size_t i = 0;
    for (double r : g.sweep_rates) {
      if (!(r > 0)) throw io::InputError(io::where(test.file) + "sweep rates must be > 0");
      one.columns.assign(out.names.size(), {});
      Driver<Model> drv(test, p, set);
      ElementState x = drv.initial_state();
      const Segment s{0.0, g.sweep_strain / r, g.direction * r, g.direction * r};
      drv.run(x, {s}, {s.t1}, one, {});
      for (std::size_t c = 0; c < out.columns.size(); ++c) out.columns[c].push_back(one.columns[c].back());
      out.stats.rhs_evals += one.stats.rhs_evals;
      out.stats.steps += one.stats.steps;
      out.stats.events += one.stats.events;
      out.stats.vs_clamped += one.stats.vs_clamped;
      out.stats.tension_cutoff = out.stats.tension_cutoff || one.stats.tension_cutoff;
      one.stats = RunStats{};
      if (progress) progress(double(++i) / g.sweep_rates.size());
    }
  }
  out.stats.cpu_seconds = cpu_now() - c0;
  return out;
}

void check_test(const ElementTest& t) {
  const std::string w = io::where(t.file);
  const auto& g = t.programme;
  if (g.kind != ProgrammeKind::Sweep && !(g.duration > 0)) throw io::InputError(w + "duration must be > 0");
  if (g.kind == ProgrammeKind::Sweep && !(g.sweep_strain > 0)) throw io::InputError(w + "sweep_strain must be > 0");
  if (t.solver.kind == SolverKind::Cvode && !(t.solver.rtol > 0 && t.solver.atol > 0))
    throw io::InputError(w + "rtol and atol must be > 0");
  if (t.solver.kind == SolverKind::Incremental && !(t.solver.dt > 0)) throw io::InputError(w + "dt must be > 0");
  if (!(t.initial.sigma_v0 > 0)) throw io::InputError(w + "sigma_v0 must be > 0");
  if (g.rate < 0) throw io::InputError(w + "rate must be >= 0");
  if (g.kind == ProgrammeKind::Data && !(g.rate > 0)) throw io::InputError(w + "programme 'data' needs rate > 0");
  if (g.direction != 1.0 && g.direction != -1.0) throw io::InputError(w + "direction must be +1 or -1");
  if (g.kind == ProgrammeKind::Data && g.control == Control::Stress && t.path != LoadingPath::Oedometric)
    throw io::InputError(w + "stress control needs the oedometric path");
}

}  // namespace

ResultTable run_element_test(const ElementTest& test, const io::ParameterSet& set, const ProgressCallback& progress) {
  check_test(test);
  {
    // The test's e0 against the set's V_sd: the message names the test file (where e0 is set).
    io::ParameterSet named = set;
    if (!test.file.empty()) named.file = test.file;
    io::check_initial_void_ratio(named, test.initial.e0,
                                 "'test.e0'" + (set.file.empty() ? std::string() : " (V_sd from " + set.file + ")"));
  }
  ModelChoice m = test.model;
  if (m == ModelChoice::Auto)
    m = set.has_frictional() && set.has_collisional() ? ModelChoice::PhaseTransition
        : set.has_frictional()                        ? ModelChoice::Frictional
                                                      : ModelChoice::Collisional;
  const std::string w = io::where(test.file.empty() ? set.file : test.file);
  switch (m) {
    case ModelChoice::Frictional:
      if (!set.has_frictional()) throw io::InputError(w + "model 'frictional' needs a [frictional] table in " + set.file);
      return run_model<FrictionalModel<double>>(test, *set.frictional, set, progress);
    case ModelChoice::Collisional:
      if (!set.has_collisional())
        throw io::InputError(w + "model 'collisional' needs a [collisional] table in " + set.file);
      return run_model<CollisionalModel<double>>(test, *set.collisional, set, progress);
    default: {
      const PhaseTransitionParams<double> p = set.phase_transition();
      return run_model<PhaseTransitionModel<double>>(test, p, set, progress);
    }
  }
  throw io::InputError(w + "unsupported model choice");
}

}  // namespace granflow::elementtest
