#include "SweepCommand.hpp"

#include <memory>

#include "mmval/validate/Sweep.hpp"

namespace mmval::app {

void registerSweepCommand(CLI::App& app, const CaseKindRegistry& registry) {
  auto o = std::make_shared<validate::SweepOptions>();
  CLI::App* sw = app.add_subcommand("sweep", "Run one case over key values and seeds: each metric's spread over seeds, its band over settings");
  sw->add_option("case", o->file, "Case file (TOML)")->required();
  sw->add_option("--out", o->out, "Output folder: runs/run-NNN/ per run, sweep.csv, sweep.json (and sweep.svg)")->required();
  sw->add_option("--vary", o->vary, "KEY=V1,V2,...: values of a case key (repeatable; the runs are every combination)");
  sw->add_option("--seeds", o->seeds, "Runs per setting with seeds 1..N of the kind's seed key (statistics over them)")->check(CLI::Range(1, 100));
  sw->add_option("--seed-key", o->seed_key, "The key the seeds go to (default: the kind's one key named *.seed)");
  sw->add_option("--set", o->set, "KEY=VALUE: set a key in every run (as mmval run --set)");
  sw->add_option("--metric", o->metrics, "Show (and plot the first) only these metrics (repeatable; default: show all)");
  sw->add_flag("--resume", o->resume, "Keep the complete runs already in the output folder and resume interrupted ones");
  sw->add_flag("--quiet", o->quiet, "No progress output from the runs");
  sw->callback([o, &registry] { validate::runSweep(*o, registry); });
}

}  // namespace mmval::app
