// CSV columns through libfccp: good files read, malformed ones give file:line errors.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include <granflow/io/csv_table.hpp>
#include <granflow/io/input_error.hpp>

using namespace granflow;

namespace {

// A CSV file in the temporary folder, removed again. The process id in its name keeps tests
// that ctest runs in parallel (and other checkouts on the machine) from sharing a file.
struct TempCsv {
  std::string path;
  TempCsv(const std::string& name, const std::string& text)
      : path((std::filesystem::temp_directory_path() /
              ("granflow_test_" + std::to_string(::getpid()) + "_" + name + ".csv"))
                 .string()) {
    std::ofstream(path) << text;
  }
  ~TempCsv() {
    std::error_code ec;
    std::filesystem::remove(path, ec);
  }
};

void expect_error(const std::string& text, const std::vector<std::string>& cols, const std::string& needle,
                  bool check_increasing = false) {
  const TempCsv file("bad", text);
  const std::string& path = file.path;
  try {
    const auto t = io::read_csv_columns(path, cols);
    if (check_increasing) io::require_strictly_increasing(t, cols.front());
    FAIL() << "no error for:\n" << text;
  } catch (const io::InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(needle), std::string::npos) << "'" << needle << "' not in: " << msg;
  }
}

}  // namespace

TEST(Csv, ReadsNamedColumnsInAnyOrder) {
  const TempCsv file("good", "# comment\nlabel,x,y\na,1,10\nb,2.5,2e1\n");
  const std::string& path = file.path;
  const auto t = io::read_csv_columns(path, {"y", "x"});
  ASSERT_EQ(t.rows(), 2u);
  EXPECT_EQ(t.column("x")[1], 2.5);
  EXPECT_EQ(t.column("y")[1], 20.0);
  EXPECT_EQ(t.lines[0], 3);
  EXPECT_EQ(io::read_csv_text_column(path, "label")[1], "b");
}

TEST(Csv, ShippedDemDataReads) {
  const auto t = io::read_csv_columns(std::string(GRANFLOW_SOURCE_DIR) +
                                          "/data/dem_steady_shear/steady_simple_shear_mu0_mu05.csv",
                                      {"solid_fraction_nu", "p_dimless", "s_dimless", "T_dimless", "restitution_e"});
  EXPECT_EQ(t.rows(), 149u);
}

TEST(Csv, MalformedFilesNameFileAndLine) {
  expect_error("x,y\n1,2\n3,abc\n", {"x", "y"}, ":3: column 'y': 'abc' is not a number");
  expect_error("x,y\n1,2\n3,nan\n", {"x", "y"}, ":3: column 'y': 'nan' is not a finite number");
  expect_error("x,y\n1,2\n3,\n", {"x", "y"}, ":3: column 'y': empty cell");
  expect_error("x,y\n1,2\n", {"x", "z"}, "z");
  expect_error("x;y\n1;2\n", {"x", "y"}, "delimiter must be a comma");
  expect_error("x,y\n", {"x", "y"}, "no data rows");
  expect_error("", {"x"}, "");
  expect_error("x,y\n1,2\n1,3\n", {"x", "y"}, ":3: column 'x' must increase strictly", true);
  expect_error("x,y\n2,2\n1,3\n", {"x", "y"}, ":3:", true);
  expect_error("x,y\n1,2,3\n", {"x", "y"}, "");
}

TEST(Csv, MissingFile) {
  EXPECT_THROW(io::read_csv_columns("/nonexistent/file.csv", {"x"}), io::InputError);
}

// A UTF-8 byte-order mark (as spreadsheet programs write it) before the header is skipped, also
// before a leading comment; line numbers count as without it.
TEST(Csv, ByteOrderMarkBeforeTheHeaderIsSkipped) {
  const std::string bom = "\xEF\xBB\xBF";
  const auto t = io::read_csv_columns(TempCsv("bom", bom + "gamma,sigma_n,tau\n0,100,30\n0.1,100,45\n").path,
                                      {"gamma", "tau"});
  ASSERT_EQ(t.rows(), 2u);
  EXPECT_EQ(t.column("tau")[1], 45.0);
  EXPECT_EQ(t.lines[0], 2);
  const auto c = io::read_csv_columns(TempCsv("bom_comment", bom + "# lab\r\nx,y\r\n1,2\r\n").path, {"x", "y"});
  EXPECT_EQ(c.lines[0], 3);
  EXPECT_EQ(io::parse_csv_columns(bom + "x\n1\n", "mem.csv", {"x"}).column("x")[0], 1.0);
  // A message quotes the header without the mark.
  expect_error(bom + "x,y\n1,2\n", {"z"}, "Header found: 'x,y'");
}

TEST(Csv, HeaderLineSkipsMarkCommentsBlankLinesAndCarriageReturn) {
  std::istringstream a("\xEF\xBB\xBF# lab\r\n\r\n\nx,y\r\n1,2\r\n");
  const io::CsvHeaderLine h = io::find_csv_header(a);
  EXPECT_EQ(h.line, 4);
  EXPECT_EQ(h.text, "x,y");
  std::istringstream b("# only a comment\n");
  EXPECT_EQ(io::find_csv_header(b).line, 0);
  std::istringstream c("x\n\xEF\xBB\xBFy\n");  // a mark only counts at the start of the text
  EXPECT_EQ(io::find_csv_header(c).text, "x");
}

// Subnormal numbers are finite numbers (strtod flags them with ERANGE); values below the
// smallest subnormal round to 0; only overflow is not finite.
TEST(Csv, SubnormalNumbersAreFinite) {
  const TempCsv file("subnormal", "x,y\n1,1e-310\n2,-4.9e-324\n3,2.2250738585072014e-308\n4,1e-400\n");
  const auto t = io::read_csv_columns(file.path, {"x", "y"});
  const auto& y = t.column("y");
  ASSERT_EQ(y.size(), 4u);
  EXPECT_EQ(y[0], 1e-310);
  EXPECT_EQ(y[1], -std::numeric_limits<double>::denorm_min());
  EXPECT_EQ(y[2], std::numeric_limits<double>::min());
  EXPECT_EQ(y[3], 0.0);
  expect_error("x,y\n1,1e400\n", {"x", "y"}, ":2: column 'y': '1e400' is not a finite number");
  expect_error("x,y\n1,-1e309\n", {"x", "y"}, "'-1e309' is not a finite number");
}
