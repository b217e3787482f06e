// Command-line spelling of the CUDA backend's options (granflow mpm, granflow bench mpm).
#include <cstdlib>
#include <string>

#include <granflow/mpm/runner.hpp>

namespace granflow::mpm {

namespace {

bool on_off(const std::string& v, bool& out) {
  if (v == "on" || v == "1" || v == "true") {
    out = true;
    return true;
  }
  if (v == "off" || v == "0" || v == "false") {
    out = false;
    return true;
  }
  return false;
}

bool count(const std::string& v, int lo, int hi, int& out) {
  char* end = nullptr;
  const long x = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || x < lo || x > hi) return false;
  out = static_cast<int>(x);
  return true;
}

}  // namespace

bool set_cuda_option(CudaOptions& o, const std::string& name, const std::string& value) {
  if (name == "graphs") return on_off(value, o.graphs);
  if (name == "graph-steps") return count(value, 1, 1024, o.graph_steps);
  if (name == "sort") return count(value, 0, 1 << 30, o.sort_every);
  if (name == "g2p-block") {
    int b = 0;
    if (!count(value, 32, 256, b) || b % 32 != 0) return false;
    o.g2p_block = b;
    return true;
  }
  if (name == "g2p-regcap") return on_off(value, o.g2p_reg_cap);
  if (name == "update-stats") return on_off(value, o.update_stats);
  if (name == "g2p-split") {
    bool on = false;
    if (value == "auto") o.g2p_split = CudaOptions::Split::Auto;
    else if (on_off(value, on)) o.g2p_split = on ? CudaOptions::Split::On : CudaOptions::Split::Off;
    else return false;
    return true;
  }
  if (name == "p2g") {
    if (value == "atomic") o.p2g = CudaOptions::P2G::Atomic;
    else if (value == "warp") o.p2g = CudaOptions::P2G::Warp;
    else if (value == "tile") o.p2g = CudaOptions::P2G::Tile;
    else return false;
    return true;
  }
  return false;
}

}  // namespace granflow::mpm
