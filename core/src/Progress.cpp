#include "mmval/core/Progress.hpp"

#include <unistd.h>

#include <cstdio>

namespace mmval {

Progress::Progress(std::string label, std::size_t total, bool quiet)
    : m_label(std::move(label)), m_total(total), m_quiet(quiet), m_tty(isatty(STDERR_FILENO) != 0),
      m_start(std::chrono::steady_clock::now()), m_last_draw(m_start) {}

Progress::~Progress() { finish(); }

void Progress::update(std::size_t done) {
  m_done = done;
  if (m_quiet || m_finished) return;
  const auto now = std::chrono::steady_clock::now();
  if (m_tty) {
    if (now - m_last_draw < std::chrono::milliseconds(100)) return;
    m_last_draw = now;
    draw(false);
  } else if (m_total > 0) {
    const int decile = static_cast<int>(10 * m_done / m_total);
    if (decile != m_last_decile) {
      m_last_decile = decile;
      draw(false);
    }
  }
}

void Progress::finish() {
  if (m_quiet || m_finished) return;
  m_finished = true;
  draw(true);
}

void Progress::draw(bool final_line) {
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
  const double rate = elapsed > 0 ? m_done / elapsed : 0.0;
  char line[256];
  if (m_total > 0) {
    const double f = static_cast<double>(m_done) / static_cast<double>(m_total);
    const int width = 30, filled = static_cast<int>(f * width + 0.5);
    std::string bar(filled, '#');
    bar.resize(width, '.');
    const double left = rate > 0 ? (m_total - m_done) / rate : 0.0;
    std::snprintf(line, sizeof line, "%s [%s] %zu/%zu %.1f/s %s %.0fs", m_label.c_str(), bar.c_str(), m_done, m_total,
                  rate, final_line ? "took" : "left", final_line ? elapsed : left);
  } else {
    std::snprintf(line, sizeof line, "%s %zu done, %.1f/s, %.0fs", m_label.c_str(), m_done, rate, elapsed);
  }
  if (m_tty)
    std::fprintf(stderr, "\r%s\033[K%s", line, final_line ? "\n" : "");
  else
    std::fprintf(stderr, "%s\n", line);
}

}  // namespace mmval
