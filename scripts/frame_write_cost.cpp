// Cost of one VTU frame on the CPU (issue 49): a full 3D frame of N points (default 2e6) with
// every array, written in each format, then the manifest over the folder; and the copy the time
// loop now makes to hand a frame to the writer thread. Best of R repetitions (default 3).
//   ./frame_write_cost DIR [N] [R]
// Built against a build tree's libraries (here build-t/, a Release build of this tree):
//   g++ -O2 -std=c++17 -fopenmp -I mpm/include -I io/include -I constitutive/include \
//       -isystem /usr/include/eigen3 scripts/frame_write_cost.cpp build-t/mpm/libgranflow_mpm.a \
//       build-t/io/libgranflow_io.a -ltomlplusplus -lgdal -o /tmp/frame_write_cost   (-lgdal: a GDAL build)
// With -DBEFORE_ISSUE_49 and the libraries of an older build (6fd3395) it times the code before:
// base64 only (then called "binary"), the manifest reading every file back.
#include <fcntl.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>

#include <granflow/io/output.hpp>
#include <granflow/io/run_folder.hpp>
#include <granflow/mpm/driver.hpp>

using namespace granflow;
namespace fs = std::filesystem;

namespace {

double best_of(int reps, const std::function<void()>& f) {
  double best = 1e300;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

mpm::Frame make_frame(long n) {
  mpm::Frame f;
  f.n = n;
  f.dim = 3;
  long k = 0;
  auto fill = [&](std::vector<double>& v, long size) {
    v.resize(size);
    for (long i = 0; i < size; ++i, ++k) v[i] = std::sin(0.001 * k) / 3.0;
  };
  fill(f.x, 3 * n);
  fill(f.v, 3 * n);
  for (auto* a : {&f.T, &f.p, &f.q, &f.eps_pd, &f.eta_c, &f.K_col, &f.e, &f.sxx, &f.syy, &f.sxy}) fill(*a, n);
  f.material.assign(n, 0);
  f.body.assign(n, 0);
  return f;
}

// The modification time moved by a second: the file is no longer the one committed, and the
// manifest reads it back as it did for every file before issue 49.
void touch(const std::string& path) {
  struct stat st {};
  ::stat(path.c_str(), &st);
  const struct timespec t[2] = {{st.st_atim.tv_sec + 1, 0}, {st.st_mtim.tv_sec + 1, 0}};
  ::utimensat(AT_FDCWD, path.c_str(), t, 0);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s DIR [N] [R]\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  const long n = argc > 2 ? std::atol(argv[2]) : 2000000;
  const int reps = argc > 3 ? std::atoi(argv[3]) : 3;
  fs::remove_all(dir);
  fs::create_directories(dir);
  const mpm::Frame fr = make_frame(n);
  std::printf("%ld points, 3D, every array; best of %d\n", n, reps);
  auto report = [&](const char* what, double s, const std::string& file) {
    const double mb = file.empty() ? 0 : fs::file_size(file) / 1e6;
    std::printf("%-48s %7.3f s", what, s);
    if (mb > 0) std::printf("  %7.1f MB  %6.0f MB/s", mb, mb / s);
    std::printf("\n");
  };
  const std::string b64 = dir + "/frame_base64.vtu";
#ifdef BEFORE_ISSUE_49
  report("write_vtu base64 (Buffered)", best_of(reps, [&] { mpm::write_vtu(b64, fr, true); }), b64);
  touch(b64);
  report("write_manifest (read back, hash, fsync)", best_of(reps, [&] { io::write_manifest(dir, "complete"); }), "");
#else
  const std::string raw = dir + "/frame_raw.vtu";
  report("frame copy (the loop's hand-over)", best_of(reps, [&] { mpm::Frame copy = fr; (void)copy; }), "");
  report("write_vtu base64 (Buffered)", best_of(reps, [&] { mpm::write_vtu(b64, fr, mpm::FrameFormat::Base64); }), b64);
  report("write_vtu raw (Buffered)", best_of(reps, [&] { mpm::write_vtu(raw, fr, mpm::FrameFormat::Raw); }), raw);
  report("write_vtu raw (Sync, as the writer thread)",
         best_of(reps, [&] { mpm::write_vtu(raw, fr, mpm::FrameFormat::Raw, {}, io::Durability::Sync); }), raw);
  fs::remove(b64);
  report("write_manifest (raw frame as committed)", best_of(reps, [&] { io::write_manifest(dir, "complete"); }), "");
  report("write_manifest (raw frame read back)", best_of(reps, [&] { touch(raw); io::write_manifest(dir, "complete"); }), "");
#endif
  fs::remove_all(dir);
  return 0;
}
