// Case files hold parameters and a short header; studies behind a case's numbers live in
// docs/validation/ pages, and every page a case file names exists.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

namespace {

namespace fs = std::filesystem;

constexpr int kMaxHeaderLines = 40;  // a case's purpose, sources, assumptions and cost; the rest is a docs page

TEST(CaseHeader, EveryCaseFileHasAShortHeaderAndNamesPagesThatExist) {
  const fs::path root = MMVAL_SOURCE_DIR;
  const std::regex page(R"(docs/validation/[A-Za-z0-9_.-]+\.md)");
  int files = 0;
  for (const auto& entry : fs::directory_iterator(root / "cases")) {
    if (entry.path().extension() != ".toml") continue;
    ++files;
    std::ifstream in(entry.path());
    std::string line;
    int header = 0;
    bool in_header = true;
    while (std::getline(in, line)) {
      if (in_header && !line.empty() && line[0] == '[') in_header = false;
      if (in_header && !line.empty() && line[0] == '#') ++header;
      for (std::sregex_iterator m(line.begin(), line.end(), page), end; m != end; ++m)
        EXPECT_TRUE(fs::exists(root / m->str())) << entry.path().filename() << " names " << m->str() << ", which does not exist";
    }
    EXPECT_LE(header, kMaxHeaderLines) << entry.path().filename() << ": a header of " << header
                                       << " comment lines; move the study into a docs/validation/ page";
  }
  EXPECT_GT(files, 20);
}

}  // namespace
