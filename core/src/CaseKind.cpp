#include "mmval/core/CaseKind.hpp"

#include <stdexcept>

namespace mmval {

void CaseKindRegistry::add(CaseKind kind) {
  if (kind.name.empty() || !kind.run || !kind.declare) throw std::logic_error("case kind without name, declare or run");
  if (m_kinds.count(kind.name) != 0) throw std::logic_error("case kind '" + kind.name + "' registered twice");
  m_kinds.emplace(kind.name, std::move(kind));
  rebuildSchemas();
}

void CaseKindRegistry::rebuildSchemas() {
  // Every schema lists every kind in case.kind's choices, so rebuild them all.
  m_schemas.clear();
  const auto all = names();
  for (const auto& [name, k] : m_kinds) {
    auto schema = std::make_unique<Schema>(name, k.summary);
    declareCommonKeys(*schema, all);
    k.declare(*schema);
    if (k.metrics) k.metrics(*schema);
    m_schemas.emplace(name, std::move(schema));
  }
}

void CaseKindRegistry::declareMetrics(std::string_view name, std::function<void(Schema&)> metrics) {
  auto it = m_kinds.find(name);
  if (it == m_kinds.end()) throw std::logic_error("no case kind '" + std::string(name) + "' to declare metrics for");
  it->second.metrics = std::move(metrics);
  rebuildSchemas();
}

void CaseKindRegistry::replaceRunner(std::string_view name, std::function<RunOutput(const Case&, const RunContext&)> run) {
  auto it = m_kinds.find(name);
  if (it == m_kinds.end()) throw std::logic_error("no case kind '" + std::string(name) + "' to give a runner");
  it->second.run = std::move(run);
}

const CaseKind* CaseKindRegistry::find(std::string_view name) const {
  auto it = m_kinds.find(name);
  return it == m_kinds.end() ? nullptr : &it->second;
}

const Schema& CaseKindRegistry::schema(std::string_view name) const {
  auto it = m_schemas.find(name);
  if (it == m_schemas.end()) throw std::logic_error("no case kind '" + std::string(name) + "'");
  return *it->second;
}

std::vector<std::string> CaseKindRegistry::names() const {
  std::vector<std::string> out;
  for (const auto& [name, k] : m_kinds) out.push_back(name);
  return out;
}

}  // namespace mmval
