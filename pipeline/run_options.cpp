#include "pipeline/run_options.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <new>
#include <nlohmann/json.hpp>
#include <limits>
#include <optional>
#include <set>
#include <type_traits>

#include "core/error.h"
#include "core/format.h"
#include "pipeline/option_registry.h"

namespace skyfall {
namespace {

using json = nlohmann::json;
constexpr const char* kSchema = "skyfall.run_options/1";

// The IO objects the registry (option_registry.h) is visited with: JSON
// writer and strict reader, the option describer and the completeness check.

class Writer {
 public:
  explicit Writer(json* out) : out_(out) {}
  template <class T>
  void operator()(const char* key, const T& value, const char* /*help*/ = nullptr, const OptionRange& = {}) {
    if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      (*out_)[key] = {value.x(), value.y(), value.z()};
    } else if constexpr (std::is_enum_v<T>) {
      (*out_)[key] = EnumName(value);
    } else if constexpr (kIsOptionLeaf<T>) {
      (*out_)[key] = value;
    } else {
      json nested = json::object();
      Writer inner(&nested);
      Visit(inner, const_cast<T&>(value));
      (*out_)[key] = nested;
    }
  }

 template <class T>
  void NotAnOption(const T&) {}

 private:
  json* out_;
};

// Reads fields present in `in`; a key no field claims, or a value of the wrong
// JSON type, is an error naming the dotted path.
class Reader {
 public:
  Reader(const json& in, std::string path, std::string subject)
      : in_(in), path_(std::move(path)), subject_(std::move(subject)) {
    if (!in_.is_object()) Fail(path_.empty() ? "the document" : path_, "must be a JSON object");
  }
  template <class T>
  void operator()(const char* key, T& value, const char* /*help*/ = nullptr, const OptionRange& = {}) {
    seen_.insert(key);
    const auto it = in_.find(key);
    if (it == in_.end()) return;
    const std::string path = path_.empty() ? key : path_ + "." + key;
    const json& v = *it;
    if constexpr (std::is_enum_v<T>) {
      const std::optional<T> mode = v.is_string() ? EnumFromName<T>(v.get<std::string>()) : std::nullopt;
      if (!mode) Fail(path, v.dump() + " is not one of " + EnumChoices<T>());
      value = *mode;
    } else if constexpr (std::is_same_v<T, bool>) {
      if (!v.is_boolean()) Fail(path, "must be true or false, got " + v.dump());
      value = v.get<bool>();
    } else if constexpr (std::is_integral_v<T>) {
      if (!v.is_number_integer()) Fail(path, "must be a whole number, got " + v.dump());
      if (std::is_unsigned_v<T> && v.get<std::int64_t>() < 0 && !v.is_number_unsigned())
        Fail(path, "must not be negative, got " + v.dump());
      const bool fits = v.is_number_unsigned()
                            ? v.get<std::uint64_t>() <= static_cast<std::uint64_t>(std::numeric_limits<T>::max())
                            : v.get<std::int64_t>() >= static_cast<std::int64_t>(std::numeric_limits<T>::min()) &&
                                  (std::is_unsigned_v<T> || v.get<std::int64_t>() <= static_cast<std::int64_t>(
                                                                                          std::numeric_limits<T>::max()));
      if (!fits) Fail(path, "is out of range, got " + v.dump());
      value = v.get<T>();
    } else if constexpr (std::is_floating_point_v<T>) {
      if (!v.is_number()) Fail(path, "must be a number, got " + v.dump());
      if (std::abs(v.get<double>()) > std::numeric_limits<T>::max()) Fail(path, "is out of range, got " + v.dump());
      value = v.get<T>();
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (!v.is_string()) Fail(path, "must be a string, got " + v.dump());
      value = v.get<std::string>();
    } else if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
        Fail(path, "must be an array of 3 numbers, got " + v.dump());
      value = Eigen::Vector3d(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    } else {
      Reader inner(v, path, subject_);
      Visit(inner, value);
      inner.RejectUnknown();
    }
  }
  template <class T>
  void NotAnOption(const T&) {}
  void RejectUnknown(const std::set<std::string>& also_allowed = {}) const {
    for (const auto& [key, unused] : in_.items()) {
      if (!seen_.count(key) && !also_allowed.count(key))
        Fail(path_.empty() ? key : path_ + "." + key, "is not a known option");
    }
  }

 private:
  [[noreturn]] void Fail(const std::string& path, const std::string& what) const {
    throw Error("run options", subject_.empty() ? path : subject_ + ": " + path, what);
  }
  const json& in_;
  std::string path_, subject_;
  std::set<std::string> seen_;
};

// Marks the bytes of every visited field of one object, recursively; the
// innermost struct around each byte names it in a report.
class Coverage {
 public:
  Coverage(const unsigned char* base, std::vector<bool>* claimed, std::vector<std::string>* owner, std::string path)
      : base_(base), claimed_(claimed), owner_(owner), path_(std::move(path)) {}
  template <class T>
  void operator()(const char* key, T& value, const char* /*help*/ = nullptr, const OptionRange& = {}) {
    const std::string path = path_.empty() ? key : path_ + "." + key;
    if constexpr (kIsOptionLeaf<T>) {
      Claim(value);
    } else {
      Own(value, path);
      Coverage inner(base_, claimed_, owner_, path);
      Visit(inner, value);
    }
  }
  template <class T>
  void NotAnOption(T& value) { Claim(value); }
  // The struct at `path` owns its bytes until a deeper one claims them.
  template <class T>
  void Own(T& value, const std::string& path) {
    const std::size_t at = Offset(value);
    for (std::size_t k = at; k < at + sizeof(T); ++k) (*owner_)[k] = path;
  }

 private:
  template <class T>
  std::size_t Offset(T& value) const {
    return static_cast<std::size_t>(reinterpret_cast<const unsigned char*>(&value) - base_);
  }
  template <class T>
  void Claim(T& value) {
    const std::size_t at = Offset(value);
    for (std::size_t k = at; k < at + sizeof(T); ++k) (*claimed_)[k] = true;
  }
  const unsigned char* base_;
  std::vector<bool>* claimed_;
  std::vector<std::string>* owner_;
  std::string path_;
};

// One row per option: dotted path, type, default and help.
class Describer {
 public:
  Describer(std::vector<OptionDescription>* rows, std::string path) : rows_(rows), path_(std::move(path)) {}
  template <class T>
  void operator()(const char* key, T& value, const char* help = nullptr, const OptionRange& range = {}) {
    const std::string path = path_.empty() ? key : path_ + "." + key;
    if constexpr (kIsOptionLeaf<T>) {
      json holder = json::object();
      Writer w(&holder);
      w(key, value);
      std::vector<std::string> choices;
      if constexpr (std::is_enum_v<T>) choices = EnumNameList<T>();
      rows_->push_back({path, TypeName<T>(), holder[key].dump(), UnitOfKey(key), help ? help : "", choices, range});
    } else {
      Describer inner(rows_, path);
      Visit(inner, value);
    }
  }
  template <class T>
  void NotAnOption(const T&) {}

 private:
  template <class T>
  static std::string TypeName() {
    if constexpr (std::is_enum_v<T>) return "mode";
    else if constexpr (std::is_same_v<T, bool>) return "bool";
    else if constexpr (std::is_integral_v<T>) return "integer";
    else if constexpr (std::is_floating_point_v<T>) return "number";
    else if constexpr (std::is_same_v<T, std::string>) return "string";
    else return "3 numbers";
  }
  std::vector<OptionDescription>* rows_;
  std::string path_;
};

// Every numeric value against the range the registry declares for it.
template <class T>
json ToJson(const T& options) {
  json out = json::object();
  Writer w(&out);
  Visit(w, const_cast<T&>(options));
  return out;
}

json RunJson(const RunOptions& o) {
  json out = {{"schema", kSchema}};
  out.update(ToJson(o));
  return out;
}

// Runs a section's Check() and puts the section in front of the field.
template <class F>
void CheckSection(const char* section, F check) {
  try {
    check();
  } catch (const Error& e) {
    throw Error("run options", std::string(section) + "." + e.subject(), e.detail());
  }
}

}  // namespace

void TrainStageOptions::Check() const {
  CheckOptionRanges(*this, "train");
  optimizer.Check();
  if (depth_prior != "surface" && depth_prior != "none" && depth_prior.rfind("cmd:", 0) != 0)
    throw Error("train", "depth_prior", "'" + depth_prior + "' is not one of surface, none, cmd:COMMAND");
  if (depth_prior == "cmd:") throw Error("train", "depth_prior", "'cmd:' names no command");
}

void IduStageOptions::Check() const {
  if (refiner != "reproject" && (refiner.rfind("cmd:", 0) != 0 || refiner.size() == 4))
    throw Error("idu", "refiner", "'" + refiner + "' is not 'reproject' or 'cmd:COMMAND'");
  options.Check();
  reproject.Check();
  auto_decision.Check();
}

void MergeOptions::Check() const { CheckOptionRanges(*this, "merge"); }

void DsmOptions::Check() const { CheckOptionRanges(*this, "dsm"); }

void ExportOptions::Check() const { CheckOptionRanges(*this, "exports"); }

void SlurmOptions::Check() const {
  CheckOptionRanges(*this, "slurm");
  // These go into job scripts: refuse what would break out of an #SBATCH line.
  for (const auto& [name, value] : {std::pair<const char*, const std::string&>{"partition", partition},
                                    {"account", account}, {"time_limit", time_limit}}) {
    if (value.find_first_of(" \t\n'\"$`;\\") != std::string::npos) {
      throw Error("slurm", name, "'" + value + "' holds a space, quote or shell character");
    }
  }
}

void ExecutorOptions::Check() const {
  CheckOptionRanges(*this, "executor");
  try {
    slurm.Check();
  } catch (const Error& e) {
    throw Error("executor", "slurm." + e.subject(), e.detail());
  }
}

void ProductOptions::Check() const {
  CheckOptionRanges(*this, "products");
  if (vertical_datum == HeightReference::kAboveTerrain)
    throw Error("products", "vertical_datum", "must be 'ellipsoid' or 'egm96' (above_terrain is the nDSM's, not a datum)");
}

void RunOptions::Check() const {
  CheckOptionRanges(*this, "run options");
  CheckSection("ingest", [&] { ingest.Check(); });
  CheckSection("tiling", [&] { tiling.Check(); });
  CheckSection("sfm", [&] { sfm.Check(); });
  CheckSection("dense", [&] { dense.Check(); });
  CheckSection("train", [&] { train.Check(); });
  CheckSection("idu", [&] { idu.Check(); });
  CheckSection("merge", [&] { merge.Check(); });
  CheckSection("dsm", [&] { dsm.Check(); });
  CheckSection("products", [&] { products.Check(); });
  CheckSection("exports", [&] { exports.Check(); });
  CheckSection("executor", [&] { executor.Check(); });
}

std::string RunOptionsToJson(const RunOptions& options) { return RunJson(options).dump(2) + "\n"; }

RunOptions RunOptionsFromJson(const std::string& text, const std::string& subject) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    throw Error("run options", subject, std::string("not valid JSON: ") + e.what());
  }
  if (!doc.is_object()) throw Error("run options", subject, "must be a JSON object");
  const auto found = doc.find("schema");
  if (found != doc.end() && !found->is_string()) {
    throw Error("run options", subject, "schema must be a string, got " + found->dump());
  }
  const std::string schema = found != doc.end() ? found->get<std::string>() : std::string(kSchema);
  if (schema != kSchema) throw Error("run options", subject, "schema is '" + schema + "', expected '" + kSchema + "'");
  RunOptions options;
  Reader reader(doc, "", subject);
  Visit(reader, options);
  reader.RejectUnknown({"schema"});
  return options;
}

void SetRunOption(RunOptions* options, const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw Error("run options", assignment, "expected SECTION.FIELD=VALUE, e.g. dense.sgm_p2=1.5");
  const std::string path = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  json doc = RunJson(*options);
  json* node = &doc;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = path.find('.', start);
    const std::string key = path.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (!node->is_object() || !node->contains(key) || key == "schema")
      throw Error("run options", path, "is not a known option (see `skyfall run --print-config`)");
    node = &(*node)[key];
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  if (node->is_object()) throw Error("run options", path, "is a section; set one of its fields");
  json value = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded() || node->is_string()) value = text;  // strings need no quotes
  *node = value;
  *options = RunOptionsFromJson(doc.dump(), "--set " + path);
}

std::string TileOptionsJson(const RunOptions& o) {
  const json doc = {{"sfm", ToJson(o.sfm)}, {"dense", ToJson(o.dense)}, {"train", ToJson(o.train)}, {"idu", ToJson(o.idu)}};
  return doc.dump();
}

std::string DenseOptionsJson(const DenseOptions& options) { return ToJson(options).dump(); }

std::string IduEpisodesJson(const RunOptions& o) {
  json idu = ToJson(o.idu);
  idu.erase("mode");
  idu.erase("auto");
  return json({{"sfm", ToJson(o.sfm)}, {"dense", ToJson(o.dense)}, {"train", ToJson(o.train)}, {"idu", idu}}).dump();
}

std::string SfmOptionsJson(const SfmOptions& options) { return ToJson(options).dump(); }

std::string TrainCheckpointJson(const TrainStageOptions& options) {
  json train = ToJson(options);
  for (const char* when : {"checkpoint_interval", "eval_interval", "keep_snapshots"}) train.erase(when);
  return train.dump();
}

namespace {

bool StillHolds(const json& recorded, const json& current, const json& defaults) {
  if (!recorded.is_object() || !current.is_object()) return recorded == current;
  for (auto it = recorded.begin(); it != recorded.end(); ++it)
    if (!current.contains(it.key())) return false;
  for (auto it = current.begin(); it != current.end(); ++it) {
    const json& fallback = defaults.is_object() && defaults.contains(it.key()) ? defaults.at(it.key()) : json();
    if (recorded.contains(it.key())) {
      if (!StillHolds(recorded.at(it.key()), it.value(), fallback)) return false;
    } else if (fallback.is_null() || it.value() != fallback) {
      return false;
    }
  }
  return true;
}

}  // namespace

bool SettingsStillHold(const std::string& recorded_json, const std::string& current_json,
                       const std::string& defaults_json) {
  if (recorded_json == current_json) return true;
  const json recorded = json::parse(recorded_json, nullptr, /*allow_exceptions=*/false);
  if (recorded.is_discarded()) return false;
  return StillHolds(recorded, json::parse(current_json), json::parse(defaults_json));
}

std::string UnitOfKey(const std::string& key) {
  static const std::pair<const char*, const char*> kSuffixes[] = {
      {"_m2", "m²"}, {"_px2", "px²"}, {"_m", "m"}, {"_px", "px"}, {"_deg", "deg"}, {"_s", "s"},
      {"_mb", "MB"}, {"_cells", "cells"}, {"_voxels", "voxels"}, {"_db", "dB"}};
  for (const auto& [suffix, unit] : kSuffixes) {
    const std::size_t n = std::strlen(suffix);
    if (key.size() > n && key.compare(key.size() - n, n, suffix) == 0) return unit;
  }
  return "";
}

std::vector<OptionDescription> DescribeRunOptions() {
  std::vector<OptionDescription> rows;
  RunOptions defaults;
  Describer d(&rows, "");
  Visit(d, defaults);
  return rows;
}

OptionDescription DescribeRunOption(const std::string& path) {
  for (OptionDescription& row : DescribeRunOptions())
    if (row.path == path) return row;
  throw Error("run options", path, "is not a known option (see `skyfall run --print-config`)");
}

std::string RunOptionsReferenceMarkdown() {
  std::string out, section;
  for (const OptionDescription& row : DescribeRunOptions()) {
    const std::string top = row.path.substr(0, row.path.find('.'));
    if (top != section) {
      section = top;
      out += (out.empty() ? "" : "\n") + std::string("#### `") + section + "`\n\n" +
             "| option | type | default | unit | range | meaning |\n|---|---|---|---|---|---|\n";
    }
    std::string help = row.help;
    for (std::size_t at = help.find('|'); at != std::string::npos; at = help.find('|', at + 2)) help.replace(at, 1, "\\|");
    std::string type = row.type;
    if (!row.choices.empty()) {
      type = "one of ";
      for (std::size_t k = 0; k < row.choices.size(); ++k) type += (k ? ", `" : "`") + row.choices[k] + "`";
    }
    const std::string range = row.range.Declared() ? row.range.Text() : "";
    out += "| `" + row.path + "` | " + type + " | `" + row.default_json + "` | " + row.unit + " | " + range + " | " +
           help + " |\n";
  }
  return out;
}

std::vector<std::pair<std::size_t, std::size_t>> UnclaimedFieldBytes(const std::vector<unsigned char>& a,
                                                                     const std::vector<unsigned char>& b,
                                                                     const std::vector<bool>& claimed) {
  std::vector<std::pair<std::size_t, std::size_t>> ranges;
  for (std::size_t k = 0; k < claimed.size(); ++k) {
    if (claimed[k] || a[k] != b[k]) continue;
    if (!ranges.empty() && ranges.back().second == k) {
      ranges.back().second = k + 1;
    } else {
      ranges.emplace_back(k, k + 1);
    }
  }
  return ranges;
}

std::vector<std::string> RunOptionsRegistryGaps() {
  constexpr std::size_t n = sizeof(RunOptions);
  constexpr std::align_val_t align{alignof(RunOptions)};
  unsigned char* buffer = static_cast<unsigned char*>(::operator new(n, align));
  // Two constructions at one address over different fill patterns: padding
  // keeps the fill, every initialized field writes the same bytes both times.
  std::vector<unsigned char> first(n), second(n);
  for (std::vector<unsigned char>* snapshot : {&first, &second}) {
    std::memset(buffer, snapshot == &first ? 0xA5 : 0x5A, n);
    RunOptions* o = new (buffer) RunOptions;  // default-initialized: padding is left alone
    std::memcpy(snapshot->data(), buffer, n);
    o->~RunOptions();
  }
  RunOptions* o = new (buffer) RunOptions;  // default-initialized: padding is left alone
  std::vector<bool> claimed(n, false);
  std::vector<std::string> owner(n);
  Coverage coverage(buffer, &claimed, &owner, "");
  coverage.Own(*o, "(run options)");
  Visit(coverage, *o);
  std::vector<std::string> gaps;
  for (const auto& [begin, end] : UnclaimedFieldBytes(first, second, claimed))
    gaps.push_back(owner[begin] + ": bytes " + std::to_string(begin) + "-" + std::to_string(end - 1) +
                   " are in no registry entry");
  o->~RunOptions();
  ::operator delete(buffer, align);
  return gaps;
}

}  // namespace skyfall
