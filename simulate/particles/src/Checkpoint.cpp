#include "mmval/particles/Checkpoint.hpp"

#include <fstream>
#include <sstream>

namespace mmval::particles {

std::string readBinaryFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace mmval::particles
