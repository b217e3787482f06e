// Test files from text (fuzzing, tests): the same reading as load_test_file, with `path`
// standing for the file in messages and as the folder relative rate_file paths start from.
#pragma once

#include <string>

#include <toml++/toml.h>

#include "granflow/elementtest/run.hpp"

namespace granflow::elementtest {

TestFile parse_test_file_text(const std::string& text, const std::string& path);
TestFile read_test_file(const toml::table& doc, const std::string& path);

}  // namespace granflow::elementtest
