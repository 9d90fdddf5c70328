// Studies in parts (study.h): which cells a part runs, a part's bytes, and merging parts.
#include <algorithm>
#include <filesystem>

#include "eval/part_bytes.h"
#include "util/input_file.h"
#include "walkgraph/study.h"

namespace walkgraph {

namespace fs = std::filesystem;

Status StudyShard::Validate() const {
  if (count < 1 || index < 0 || index >= count) {
    return InvalidArgument("study part " + std::to_string(index) + "/" + std::to_string(count) +
                           ": need 0 <= i < n");
  }
  return Status::Ok();
}

StatusOr<StudyShard> ParseStudyShard(const std::string& text) {
  StudyShard s;
  const size_t slash = text.find('/');
  const auto bad = [&] {
    return InvalidArgument("--shard " + text + ": expected i/n with 0 <= i < n, e.g. 0/4");
  };
  if (slash == std::string::npos) return bad();
  const std::string i = text.substr(0, slash), n = text.substr(slash + 1);
  const auto digits = [](const std::string& d) {
    return !d.empty() && d.size() <= 6 &&
           std::all_of(d.begin(), d.end(), [](char c) { return c >= '0' && c <= '9'; });
  };
  if (!digits(i) || !digits(n)) return bad();
  s.index = std::stoi(i);
  s.count = std::stoi(n);
  if (!s.Validate().ok()) return bad();
  return s;
}

namespace {

// Cost of each cell (in the study's order): runs × estimators.
std::vector<long long> CellCosts(const StudyManifest& m) {
  std::vector<long long> cost;
  for (const StudySweep& s : m.sweeps) {
    for (size_t i = 0; i < s.values.size(); ++i) {
      cost.push_back(static_cast<long long>(s.runs) * static_cast<long long>(s.estimators.size()));
    }
  }
  return cost;
}

}  // namespace

std::vector<int> StudyCellOrder(const StudyManifest& m) {
  const std::vector<long long> cost = CellCosts(m);
  std::vector<int> order(cost.size());
  for (size_t c = 0; c < order.size(); ++c) order[c] = static_cast<int>(c);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return cost[a] > cost[b]; });
  return order;
}

std::vector<int> StudyShardCells(const StudyManifest& m, const StudyShard& shard) {
  const std::vector<long long> cost = CellCosts(m);
  const int n = std::max(shard.count, 1);
  std::vector<long long> load(n, 0);
  std::vector<int> mine;
  for (int c : StudyCellOrder(m)) {
    const int to = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
    load[to] += cost[c];
    if (to == shard.index) mine.push_back(c);
  }
  std::sort(mine.begin(), mine.end());
  return mine;
}

// ------------------------------------------------------------------ bytes

namespace {

// 2: the floor figures (ipin_score_m, floor_hit_rate) in every row's stats.
constexpr const char kMagic[] = "walkgraph-study-part 3";

using internal::GetStats;
using internal::PartReader;
using internal::PartWriter;
using internal::PutStats;

void PutRow(PartWriter& w, const StudyRow& row) {
  w.String(row.estimator);
  internal::PutStatus(w, row.status);
  PutStats(w, row.stats);
  w.Int(row.stats_std ? 1 : 0);
  if (row.stats_std) PutStats(w, *row.stats_std);
  w.Int(row.failed_runs);
  w.Int(row.diverged_runs);
  w.Double(row.runtime_s);
  w.Double(row.runtime_std_s);
  w.Line();
}

StudyRow GetRow(PartReader& r) {
  StudyRow row;
  row.estimator = r.String();
  row.status = internal::GetStatus(r);
  row.stats = GetStats(r);
  if (r.Int(0, 1) == 1) row.stats_std = GetStats(r);
  row.failed_runs = static_cast<int>(r.Int(0, INT32_MAX));
  row.diverged_runs = static_cast<int>(r.Int(0, INT32_MAX));
  row.runtime_s = r.Double();
  row.runtime_std_s = r.Double();
  return row;
}

}  // namespace

std::string SerializeStudyPart(const StudyPart& part) {
  PartWriter w;
  w.String(kMagic);
  w.Int(part.shard.index);
  w.Int(part.shard.count);
  w.Int(part.claimed ? 1 : 0);
  w.String(part.manifest_path);
  w.String(part.manifest_text);
  w.Int(static_cast<long long>(part.cells.size()));
  w.Line();
  for (const StudyCell& c : part.cells) {
    w.Int(c.sweep);
    w.Int(c.value);
    w.Int(c.runs);
    w.Unsigned(c.seed);
    w.OptDouble(c.pcrb_rmse_m);
    w.OptDouble(c.pcrb_filter_rmse_m);
    w.String(c.pcrb_note);
    w.Int(static_cast<long long>(c.rows.size()));
    w.Line();
    for (const StudyRow& row : c.rows) PutRow(w, row);
  }
  w.String("end");
  w.Line();
  return w.str();
}

StatusOr<StudyPart> ParseStudyPart(const std::string& bytes, const std::string& origin) {
  PartReader r(bytes, origin, "walkgraph study part");
  if (r.String() != kMagic || !r.ok()) return r.Error();
  StudyPart part;
  part.shard.index = static_cast<int>(r.Int(0, INT32_MAX));
  part.shard.count = static_cast<int>(r.Int(1, INT32_MAX));
  part.claimed = r.Int(0, 1) == 1;
  part.manifest_path = r.String();
  part.manifest_text = r.String();
  const long long cells = r.Int(0, INT32_MAX);
  for (long long c = 0; r.ok() && c < cells; ++c) {
    StudyCell cell;
    cell.sweep = static_cast<int>(r.Int(0, INT32_MAX));
    cell.value = static_cast<int>(r.Int(0, INT32_MAX));
    cell.runs = static_cast<int>(r.Int(1, INT32_MAX));
    cell.seed = r.Unsigned();
    cell.pcrb_rmse_m = r.OptDouble();
    cell.pcrb_filter_rmse_m = r.OptDouble();
    cell.pcrb_note = r.String();
    const long long rows = r.Int(0, INT32_MAX);
    for (long long k = 0; r.ok() && k < rows; ++k) cell.rows.push_back(GetRow(r));
    part.cells.push_back(std::move(cell));
  }
  if (r.String() != "end" || !r.ok() || !r.AtEnd()) return r.Error();
  if (!part.shard.Validate().ok()) return r.Error();
  return part;
}

// ------------------------------------------------------------------ merging

namespace {

// The parts of one split of manifest `m`, by index (each exactly once).
StatusOr<std::vector<const StudyPart*>> PartsByIndex(const StudyManifest& m,
                                                     const std::vector<StudyPart>& parts) {
  if (parts.empty()) return InvalidArgument("study merge: no parts");
  const int n = parts.front().shard.count;
  std::vector<const StudyPart*> by_index(n, nullptr);
  for (const StudyPart& p : parts) {
    const std::string which =
        "study part " + std::to_string(p.shard.index) + "/" + std::to_string(p.shard.count);
    if (p.shard.count != n || !p.shard.Validate().ok()) {
      return InvalidArgument(which + ": the parts are of different splits (n = " +
                             std::to_string(n) + " and " + std::to_string(p.shard.count) + ")");
    }
    if (p.claimed != parts.front().claimed) {
      return InvalidArgument(which + ": parts of the fixed split and claimed parts mixed");
    }
    if (p.manifest_text != m.text || p.manifest_path != m.path) {
      return InvalidArgument(which + ": ran another manifest (" + p.manifest_path + ") than " +
                             m.path);
    }
    if (by_index[p.shard.index] != nullptr) return InvalidArgument(which + ": given twice");
    by_index[p.shard.index] = &p;
  }
  for (int i = 0; i < n; ++i) {
    if (by_index[i] == nullptr) {
      return InvalidArgument("study part " + std::to_string(i) + "/" + std::to_string(n) +
                             " is missing");
    }
  }
  return by_index;
}

}  // namespace

StatusOr<StudyResult> MergeStudyParts(const StudyManifest& m, const std::vector<StudyPart>& parts) {
  WG_ASSIGN_OR_RETURN(const std::vector<const StudyPart*> by_index, PartsByIndex(m, parts));
  std::vector<int> flat_base;  // index of each sweep's first cell
  int total = 0;
  for (const StudySweep& s : m.sweeps) {
    flat_base.push_back(total);
    total += static_cast<int>(s.values.size());
  }
  std::vector<const StudyCell*> cells(total, nullptr);
  for (const StudyPart* part : by_index) {
    const std::string which =
        "study part " + std::to_string(part->shard.index) + "/" + std::to_string(part->shard.count);
    std::vector<int> got;
    for (const StudyCell& c : part->cells) {
      if (c.sweep < 0 || c.sweep >= static_cast<int>(m.sweeps.size()) || c.value < 0 ||
          c.value >= static_cast<int>(m.sweeps[c.sweep].values.size())) {
        return InvalidArgument(which + ": a cell outside the manifest");
      }
      got.push_back(flat_base[c.sweep] + c.value);
      if (cells[got.back()] != nullptr) return InvalidArgument(which + ": a cell of another part");
      cells[got.back()] = &c;
    }
    if (!part->claimed && got != StudyShardCells(m, part->shard)) {
      return InvalidArgument(which + ": not the cells of that part");
    }
  }
  StudyResult result;
  result.manifest = m;
  for (size_t k = 0; k < m.sweeps.size(); ++k) {
    for (size_t i = 0; i < m.sweeps[k].values.size(); ++i) {
      const StudyCell* c = cells[flat_base[k] + i];
      if (c == nullptr) {
        return InvalidArgument("study merge: sweep '" + m.sweeps[k].name + "', value " +
                               m.sweeps[k].values[i] + " is in no part");
      }
      result.cells.push_back(*c);
    }
  }
  return result;
}

Status WriteStudyPart(const StudyPart& part, const std::string& out_dir,
                      const OutputOptions& options) {
  const std::string bytes = SerializeStudyPart(part);
  return WriteOutputFolder(out_dir, options, [&](const std::string& tmp_dir) {
    return WriteFileInOutput((fs::path(tmp_dir) / kStudyPartFile).string(), [&](std::ostream& out) {
      out << bytes;
      return true;
    });
  });
}

StatusOr<StudyResult> MergeStudyPartFiles(const std::vector<std::string>& paths,
                                          const EstimatorRegistry& registry) {
  if (paths.empty()) return InvalidArgument("study merge: no parts given");
  constexpr size_t kMaxPartBytes = size_t{1} << 30;
  std::vector<StudyPart> parts;
  for (const std::string& path : paths) {
    std::error_code ec;
    const std::string file =
        fs::is_directory(path, ec) ? (fs::path(path) / kStudyPartFile).string() : path;
    WG_ASSIGN_OR_RETURN(const std::string bytes, internal::ReadInputFile(file, kMaxPartBytes));
    WG_ASSIGN_OR_RETURN(StudyPart part, ParseStudyPart(bytes, file));
    parts.push_back(std::move(part));
  }
  WG_ASSIGN_OR_RETURN(
      const StudyManifest m,
      ParseStudyManifest(parts.front().manifest_text, parts.front().manifest_path, registry));
  return MergeStudyParts(m, parts);
}

}  // namespace walkgraph
