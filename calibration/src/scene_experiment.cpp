// MPM scenes as calibration experiments (kind = "mpm_scene"; docs/calibration.md).
#include <granflow/calibration/experiment.hpp>
#include <granflow/io/toml_reader.hpp>

namespace granflow::calibration {

std::shared_ptr<const Experiment> make_scene_experiment(io::TomlTable& t, const std::string&, std::size_t) {
  t.fail("kind", "MPM scene experiments are not built yet");
}

}  // namespace granflow::calibration
