// Built when CUDA is not available: the cuda backend reports itself missing.
#include <stdexcept>

#include <granflow/mpm/runner.hpp>

namespace granflow::mpm {

std::string cuda_unavailable_reason() { return "this granflow was built without CUDA (nvcc not found)"; }
std::unique_ptr<Runner> make_cuda_runner(const SceneSetup&, const CudaOptions&) {
  throw std::runtime_error(cuda_unavailable_reason() + "; use --backend cpu");
}
std::unique_ptr<Runner> make_cuda_runner(const SceneSetup&, const CudaOptions&, const SlabOptions&) {
  throw std::runtime_error(cuda_unavailable_reason() + "; use --backend cpu");
}
bool cuda_backend_available() { return false; }
bool cuda_memory_info(std::size_t&, std::size_t&) { return false; }
int cuda_device_count() { return 0; }
void cuda_select_device(int) {}

}  // namespace granflow::mpm
