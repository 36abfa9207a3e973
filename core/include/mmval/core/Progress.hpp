// Progress of long work on stderr: a bar with rate and time left when stderr
// is a terminal, a line every ~10 % otherwise (CI logs), nothing when quiet.
#pragma once
#include <chrono>
#include <cstddef>
#include <string>

namespace mmval {

class Progress {
 public:
  /// `total` = 0 when unknown (then only the count and rate are shown).
  Progress(std::string label, std::size_t total, bool quiet = false);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void update(std::size_t done);
  void advance(std::size_t steps = 1) { update(m_done + steps); }
  void finish();

 private:
  void draw(bool final_line);
  std::string m_label;
  std::size_t m_total, m_done = 0;
  bool m_quiet, m_tty, m_finished = false;
  int m_last_decile = -1;
  std::chrono::steady_clock::time_point m_start, m_last_draw;
};

}  // namespace mmval
