// A runner that forwards every call to another: tests derive from it to change one call (a
// signal at a chosen step, a stable step that collapses) and leave the rest as the runner does.
#pragma once

#include <string>
#include <vector>

#include <granflow/mpm/runner.hpp>

namespace granflow::mpm::test {

class ForwardingRunner : public Runner {
 public:
  explicit ForwardingRunner(Runner& r) : r_(r) {}
  void set_stage(int s, double d, double f) override { r_.set_stage(s, d, f); }
  StepResult step(double dt, bool lim) override { return r_.step(dt, lim); }
  void frame(Frame& o, bool d, const std::vector<long>& sub) override { r_.frame(o, d, sub); }
  void download(HostParticles& o) override { r_.download(o); }
  void upload(const HostParticles& i) override { r_.upload(i); }
  PhaseTimes times() const override { return r_.times(); }
  void reset_times() override { r_.reset_times(); }
  UpdateStats update_stats() const override { return r_.update_stats(); }
  std::string device() const override { return r_.device(); }
  long particles() const override { return r_.particles(); }
  long nodes() const override { return r_.nodes(); }

 private:
  Runner& r_;
};

}  // namespace granflow::mpm::test
