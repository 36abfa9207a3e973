#include "SweepCommand.hpp"

#include <map>
#include <memory>
#include <string>

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
  sw->add_option("--jobs", o->jobs,
                 "Runs at once, each as its own process (mmval run; its messages in runs/run-NNN.log while it runs, no progress of its own); "
                 "1: one after another in this process. The same tables either way, timings apart. A run whose thread count is auto "
                 "(numerics.threads = 0) takes its share of the cores, cores / N (MMVAL_AUTO_THREADS, unless set already)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  sw->add_option("--grid", o->grid_key, "A --vary key (numeric values) that is the grid resolution: its two finest levels (and the order from three) give each metric's grid part");
  sw->add_option("--step", o->step_key, "A --vary key (numeric values) that is the step size: the step part, as --grid");
  const std::map<std::string, validate::Finer> finer = {{"larger", validate::Finer::larger}, {"smaller", validate::Finer::smaller}};
  sw->add_option("--grid-finer", o->grid_finer, "Which values of --grid are finer: larger (cells per pixel; default) or smaller (a cell size)")
      ->transform(CLI::CheckedTransformer(finer, CLI::ignore_case));
  sw->add_option("--step-finer", o->step_finer, "Which values of --step are finer: smaller (a step; default) or larger (steps per unit)")
      ->transform(CLI::CheckedTransformer(finer, CLI::ignore_case));
  sw->add_option("--converged-within", o->converged_within,
                 "[METRIC=]VALUE: absolute tolerance in the metric's unit (0.02: 2 points of a fraction) of the verdict whether the grid and step parts are "
                 "within it; without METRIC for the --metric metrics (all when none is named) without their own (repeatable)");
  sw->callback([o, &registry] { validate::runSweep(*o, registry); });
}

}  // namespace mmval::app
