// Errors in files people write by hand. Every message names the file and, where known,
// the line (and column) and the key, and says what is allowed.
#pragma once

#include <stdexcept>
#include <string>

namespace granflow::io {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// "file:line:col: " or "file: " when no position is known.
std::string where(const std::string& file, long line = 0, long column = 0);

// Input that is accepted but probably not meant (strains in per cent, --devices with the CPU
// twin): one line, by default "granflow: warning: LINE" on stderr. nullptr restores the default.
void warn(const std::string& line);
void set_warning_sink(void (*sink)(const std::string& line));

}  // namespace granflow::io
