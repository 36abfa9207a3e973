// The reader of result.json used by `mmval report` (reports/Report.hpp
// collect) and the summary built from it (Summary.hpp: metricsJson, text,
// markdown, html, failures). collect() documents InputError for bad input;
// anything else escaping from it or from the summary is a finding.
#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "FuzzSupport.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/reports/Summary.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto dir = mmval::fuzz::scratchDir() / "run";
  std::filesystem::create_directories(dir);
  mmval::fuzz::writeFile(dir / "result.json", mmval::fuzz::asText(data, size));
  try {
    const mmval::reports::ReportInput input = mmval::reports::collect({dir});
    const mmval::reports::Summary& s = input.summary;
    (void)s.metricsJson().dump();
    (void)s.text();
    (void)s.markdown();
    (void)s.html();
    (void)s.failures();
  } catch (const mmval::InputError&) {
  }
  return 0;
}
