// What the walkgraph command's parts share (cli.h).
#include "cli.h"

namespace walkgraph_cli {

walkgraph::OutputOptions g_output;
std::string g_radio_map;

const MpiJob* g_job = nullptr;

bool g_ranks_share = false;

int Fail(const Status& s) {
  std::cerr << "walkgraph: " << s.message() << "\n";
  if (s.code() == walkgraph::StatusCode::kCancelled) return 128 + walkgraph::CancelSignal();
  return 1;
}

// Reads a walk and prints what it holds that is unusual but accepted (io.h
// PlausibilityWarnings: e.g. holes in the IMU stream, which the estimators bridge instead of
// integrating across); compare also counts them in results.json.
walkgraph::StatusOr<walkgraph::Walk> ReadWalk(const std::string& dir) {
  auto walk = walkgraph::ReadWalk(dir);
  if (!walk.ok()) return walk;
  for (const std::string& w : walkgraph::PlausibilityWarnings(*walk)) {
    std::cerr << "walkgraph: warning: " << dir << "/" << w << "\n";
  }
  if (g_radio_map.empty()) return walk;
  const std::string path = g_radio_map + "/anchors.csv";
  auto map = walkgraph::ReadAnchorsFile(path);
  if (!map.ok()) return map.status();
  auto applied_or = walkgraph::ApplyRadioMap(*map, &*walk);
  if (!applied_or.ok()) {
    return walkgraph::Status(applied_or.status().code(),
                             path + " on " + dir + ": " + applied_or.status().message());
  }
  const int applied = *applied_or;
  if (const Status v = walkgraph::ValidateWalk(*walk); !v.ok()) {  // e.g. a map in another frame
    return Status(v.code(), path + " on " + dir + ": " + v.message());
  }
  std::cerr << "walkgraph: " << path << ": " << applied << " of the walk's unsurveyed anchors "
            << "placed by the radio map\n";
  return walk;
}

// An error about a --config file's contents, prefixed with the file's path (the library names the
// estimator and the line, but it does not know the file).
Status InConfig(const std::string& path, const Status& s) {
  if (s.ok() || path.empty() || s.message().rfind(path, 0) == 0) return s;
  return Status(s.code(), path + ": " + s.message());
}

// After a command's outputs are written: a signal that came during the write (too late to keep
// the old output) still ends the run as interrupted.
int Finish(int rc) {
  if (rc == 0 && walkgraph::CancelRequested()) {
    std::cerr << "walkgraph: interrupted (signal " << walkgraph::CancelSignal()
              << ") after the output was complete\n";
    return 128 + walkgraph::CancelSignal();
  }
  return rc;
}

// A seed: a decimal integer in [0, 2^64 - 1] (CLI11 would wrap "-1" to 2^64 - 1).
std::string ParseSeed(const std::string& text, uint64_t* seed) {
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, *seed);
  if (text.empty() || text[0] == '-' || text[0] == '+' || ec != std::errc() || ptr != end) {
    return "--seed: expected a decimal integer in [0, 18446744073709551615], found '" +
           (text.size() > 40 ? text.substr(0, 40) + "..." : text) + "'";
  }
  return "";
}

// --estimators "a, b,c": ids without empty entries; spaces around an id are ignored.
walkgraph::StatusOr<std::vector<std::string>> SplitIds(const std::string& text) {
  std::vector<std::string> ids;
  if (walkgraph::internal::Trim(text).empty()) return ids;
  for (const std::string& field : walkgraph::internal::Split(text, ',')) {
    std::string id = walkgraph::internal::Trim(field);
    if (id.empty()) {
      return walkgraph::InvalidArgument(
          "--estimators: empty estimator id in the list; expected comma-separated ids such as "
          "fg-batch,tarrio-kf (see walkgraph list)");
    }
    ids.push_back(std::move(id));
  }
  return ids;
}

// Reads --config FILE.yaml: either the options of one estimator, or (for compare) a map from
// estimator id to its options.
walkgraph::StatusOr<YAML::Node> LoadConfig(const std::string& path) {
  if (path.empty()) return YAML::Node();
  return walkgraph::LoadYamlFile(path);
}

// Fails at once when --out would be refused at the end (see walkgraph/output.h).
Status Preflight(const std::string& out, walkgraph::OutputKind kind,
                 std::vector<std::string> inputs) {
  g_output.inputs = std::move(inputs);
  return walkgraph::CheckOutputTarget(out, kind, g_output);
}

// compare --config: a map from estimator id to that estimator's options.
Status ConfigsById(const YAML::Node& config, const std::string& path,
                   std::map<std::string, walkgraph::Config>* out) {
  if (!config.IsDefined() || config.IsNull()) return Status::Ok();
  const auto line = [&](const YAML::Node& n) { return std::to_string(n.Mark().line + 1); };
  if (!config.IsMap()) {
    return walkgraph::InvalidArgument(
        path + ":" + line(config) +
        ": expected a map from estimator id to its options, e.g. {tarrio-kf: {sigma_p_m: 0.5}}");
  }
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const auto& kv : config) {
    if (!kv.first.IsScalar() || registry.Find(kv.first.Scalar()) == nullptr) {
      std::string key = kv.first.IsScalar() ? kv.first.Scalar() : "(not a word)";
      if (key.size() > 80) key = key.substr(0, 80) + "...";
      return walkgraph::InvalidArgument(
          path + ":" + line(kv.first) + ": '" + key +
          "' is not an estimator id (see walkgraph list): compare --config takes one section "
          "per estimator, {estimator id: {option: value}}, as smooth --config also does");
    }
    // Created once here so that a bad option fails now, naming the file.
    auto estimator = registry.Create(kv.first.Scalar(), kv.second);
    if (!estimator.ok()) return InConfig(path, estimator.status());
    (*out)[kv.first.Scalar()] = kv.second;
  }
  return Status::Ok();
}

// "42 s", "3 min 07 s", "2 h 05 min", "12.5 days".
std::string Duration(double s) {
  char text[64];
  if (s < 60) {
    std::snprintf(text, sizeof(text), "%.0f s", s);
  } else if (s < 3600) {
    std::snprintf(text, sizeof(text), "%d min %02d s", int(s / 60), int(s) % 60);
  } else if (s < 2 * 86400) {
    std::snprintf(text, sizeof(text), "%d h %02d min", int(s / 3600), int(s / 60) % 60);
  } else {
    std::snprintf(text, sizeof(text), "%.1f days", s / 86400);
  }
  return text;
}

// Seconds between two progress lines in a log: 10, or WALKGRAPH_PROGRESS_INTERVAL_S (a
// number >= 0; for tests, which set 0 to see every line without a slow run).
double ProgressInterval() {
  const char* text = std::getenv("WALKGRAPH_PROGRESS_INTERVAL_S");
  if (text == nullptr || *text == '\0') return 10.0;
  char* end = nullptr;
  const double s = std::strtod(text, &end);
  return *end == '\0' && std::isfinite(s) && s >= 0.0 ? s : 10.0;
}

// "3" or "2.4" (a fraction of the units: an estimator part-way through its walk).
std::string Count(double done) {
  char text[32];
  const double whole = std::floor(done);
  if (done == whole) {
    std::snprintf(text, sizeof(text), "%.0f", done);
  } else {
    std::snprintf(text, sizeof(text), "%.1f", std::floor(done * 10) / 10);
  }
  return text;
}

void AddForce(CLI::App* command) {
  command->add_flag("--force", g_output.force,
                    "replace an existing --out folder that walkgraph did not write (one without "
                    "its .walkgraph-output marker); the input, '.', its ancestors and the home "
                    "folder are never replaced");
}

void AddThreads(CLI::App* command, int* threads, const std::string& help) {
  command->add_option("--threads", *threads, help)->check(CLI::Range(0, walkgraph::kMaxThreads));
}

// Progress of a long run on stderr with a time estimate (elapsed / done × the rest): on a
// terminal a bar redrawn in place (at most 10 times a second); else (a batch job's log) a plain
// line every ProgressInterval() s, the first after one interval (a short run prints nothing) and
// one at the end if any came before. `done` may be fractional (compare on one walk: estimators
// done plus the running one's fraction). The calls may come from several threads.
std::function<void(double, int)> MakeProgress(const std::string& prefix, const std::string& unit) {
  struct State {
    std::string prefix, unit;
    bool tty = false, printed = false;
    std::chrono::duration<double> interval;
    std::chrono::steady_clock::time_point start, last;
    std::mutex mutex;
  };
  auto st = std::make_shared<State>();
  st->prefix = prefix;
  st->unit = unit;
  st->tty = ::isatty(STDERR_FILENO) != 0;
  st->interval = std::chrono::duration<double>(st->tty ? 0.1 : ProgressInterval());
  st->start = st->last = std::chrono::steady_clock::now();
  return [st](double done, int total) {
    std::lock_guard<std::mutex> lock(st->mutex);
    const auto now = std::chrono::steady_clock::now();
    const bool end = done >= total;
    if (now - st->last < st->interval && !(end && st->printed)) return;
    st->last = now;
    st->printed = true;
    const double elapsed = std::chrono::duration<double>(now - st->start).count();
    const std::string left =
        done > 0 && !end ? ", about " + Duration(elapsed / done * (total - done)) + " left" : "";
    const double share = total > 0 ? std::min(done / total, 1.0) : 1.0;
    if (st->tty) {
      constexpr int kWidth = 30;
      const int filled = int(share * kWidth);
      std::string bar(filled, '#');
      bar.append(kWidth - filled, '-');
      std::fprintf(stderr, "\r%s[%s] %s/%d %s, %s elapsed%s\033[K", st->prefix.c_str(), bar.c_str(),
                   Count(done).c_str(), total, st->unit.c_str(), Duration(elapsed).c_str(),
                   left.c_str());
      if (end) std::fprintf(stderr, "\n");
    } else {
      std::fprintf(stderr, "%s%s/%d %s (%d%%), %s elapsed%s\n", st->prefix.c_str(),
                   Count(done).c_str(), total, st->unit.c_str(), int(share * 100),
                   Duration(elapsed).c_str(), left.c_str());
    }
    std::fflush(stderr);
  };
}

}  // namespace walkgraph_cli
