// The run's VTU frames written on a thread of their own while the time loop goes on (issue 49):
// a frame of 8e6 points is over a gigabyte, and the loop no longer waits for the disk.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "runner.hpp"

namespace granflow::mpm {

// One frame to write, in this order: the VTU (synced), the files that go with it (Buffered),
// then the index that lists it. Nothing refers back to the loop: the frame is a copy.
struct FrameJob {
  Frame frame;
  std::string path;                                         // the VTU
  std::vector<std::pair<std::string, std::string>> beside;  // (path, bytes), e.g. its pressure CSV
  std::string index_path;                                   // frames.pvd (empty: none)
  std::vector<std::pair<double, std::string>> index;        // its entries, this frame's among them
};

class FrameWriter {
 public:
  // At most `capacity` frames handed over and not yet written, the one being written included;
  // the thread starts with the first frame.
  FrameWriter(FrameFormat format, std::vector<std::string> fields, std::size_t capacity = 2);
  // Writes what was handed over (an error then is dropped: the run is ending on another) and joins.
  ~FrameWriter();
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  // Hands a frame over; blocks while `capacity` frames are pending. An earlier write's error
  // (io::OutputError naming its file) is rethrown here instead: after it, nothing is written.
  void write(FrameJob job);
  // Returns once every frame handed over is written and synced; rethrows an earlier error.
  void flush();

 private:
  void work();
  void rethrow_error();  // with the lock held

  FrameFormat format_;
  std::vector<std::string> fields_;
  std::size_t capacity_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<FrameJob> queue_;  // the front one is being written while busy_
  bool busy_ = false, stopping_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace granflow::mpm
