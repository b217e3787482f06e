// The run's files (output/output.cpp): VTU frames and their PVD index, the series CSVs and the
// final profile.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <granflow/io/output.hpp>

#include "measures.hpp"
#include "runner.hpp"

namespace granflow::mpm {

// The CSVs a run writes: dir/runout.csv and dir/tracked.csv (docs/mpm.md lists the columns),
// and a free surface (x, surface_y).
void write_series_csv(const std::string& dir, const Scene& sc, const std::vector<SeriesRow>& series,
                      const std::vector<TrackRow>& tracks);
void write_profile_csv(const std::string& path, const std::vector<std::pair<double, double>>& surface);

// Writers, through io::AtomicFile: a file appears under its name only complete; a failure
// (io::OutputError) leaves the previous file.
// `fields`: the point arrays besides position (scene.hpp frame_field_names); empty: all.
// FrameFormat::Raw writes the arrays from the frame's vectors in pieces, with no whole copy.
void write_vtu(const std::string& path, const Frame& fr, FrameFormat format, const std::vector<std::string>& fields = {},
               io::Durability durability = io::Durability::Buffered);
void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& frames);
// "frame_NNNN<tag>.vtu": a run's (and an ensemble member's) frame files, numbered from 0.
std::string frame_file_name(int number, const std::string& tag);

}  // namespace granflow::mpm
