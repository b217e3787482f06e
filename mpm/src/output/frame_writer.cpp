#include <granflow/mpm/frame_writer.hpp>

#include <pthread.h>
#include <signal.h>

#include <granflow/io/output.hpp>
#include <granflow/mpm/output.hpp>

namespace granflow::mpm {

FrameWriter::FrameWriter(FrameFormat format, std::vector<std::string> fields, std::size_t capacity)
    : format_(format), fields_(std::move(fields)), capacity_(capacity < 1 ? 1 : capacity) {}

FrameWriter::~FrameWriter() {
  {
    std::lock_guard<std::mutex> lk(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void FrameWriter::rethrow_error() {
  if (error_) std::rethrow_exception(error_);
}

void FrameWriter::write(FrameJob job) {
  std::unique_lock<std::mutex> lk(mutex_);
  changed_.wait(lk, [&] { return error_ || queue_.size() < capacity_; });
  rethrow_error();
  if (!thread_.joinable()) thread_ = std::thread([this] { work(); });  // waits for the lock
  queue_.push_back(std::move(job));
  lk.unlock();
  changed_.notify_all();
}

void FrameWriter::flush() {
  std::unique_lock<std::mutex> lk(mutex_);
  changed_.wait(lk, [&] { return queue_.empty(); });
  rethrow_error();
}

void FrameWriter::work() {
  // SIGINT and SIGTERM go to the time loop's thread, which polls them
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::unique_lock<std::mutex> lk(mutex_);
  for (;;) {
    changed_.wait(lk, [&] { return !queue_.empty() || stopping_; });
    if (queue_.empty()) return;
    FrameJob job = std::move(queue_.front());  // the husk stays in the queue: still pending
    lk.unlock();
    std::exception_ptr failed;
    try {
      write_vtu(job.path, job.frame, format_, fields_, io::Durability::Sync);
      for (const auto& [path, bytes] : job.beside) io::write_file(path, bytes, io::Durability::Buffered);
      if (!job.index_path.empty()) write_pvd(job.index_path, job.index);
    } catch (...) {
      failed = std::current_exception();
    }
    job = FrameJob{};  // the copy's memory goes before the next one is taken
    lk.lock();
    queue_.pop_front();
    if (failed) {
      error_ = failed;
      queue_.clear();  // as on a disk that stays full: the frames after it are not written
    }
    changed_.notify_all();
  }
}

}  // namespace granflow::mpm
