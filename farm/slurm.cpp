#include "farm/slurm.h"

#include "checkpoint/checkpoint.h"
#include "core/atomic_file.h"
#include "core/log.h"
#include "scheduler/driver.h"

#include <fmt/format.h>

#include <charconv>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace theia {

namespace fs = std::filesystem;

namespace {

// 'text' for the shell: single quotes, with each ' written as '\''.
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) {
    if (c == '\'')
      q += "'\\''";
    else
      q += c;
  }
  return q + "'";
}

std::string join_quoted(const std::vector<std::string>& words) {
  std::string line;
  for (const std::string& w : words) {
    if (!line.empty()) line += ' ';
    line += quote(w);
  }
  return line;
}


int parse_int(const std::string& s, const std::string& what) {
  int v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size()) throw_error("{}: '{}' is not a whole number", what, s);
  return v;
}

std::string this_binary() {
  std::error_code ec;
  fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw_error("farm submit: cannot find the theia binary ({}); use --theia", ec.message());
  return p.string();
}

// The sample ranges of a frame split n ways: [k spp / n, (k+1) spp / n).
std::vector<SampleRange> split_ranges(int spp, int n) {
  std::vector<SampleRange> r;
  for (int k = 0; k < n; ++k)
    r.push_back({uint32_t(int64_t(k) * spp / n), uint32_t(int64_t(k + 1) * spp / n)});
  return r;
}

// What every task's render shares: threads, spp, the user's options.
std::vector<std::string> common_render_args(const FarmSubmitOptions& o) {
  std::vector<std::string> a = {"--quiet", "--threads", std::to_string(o.cpus_per_task)};
  if (o.spp > 0) a.insert(a.end(), {"--spp", std::to_string(o.spp)});
  for (const std::string& w : split_words(o.render_options)) a.push_back(w);
  return a;
}

std::vector<std::string> sbatch_options(const FarmSubmitOptions& o) {
  std::vector<std::string> s = {fmt::format("--cpus-per-task={}", o.cpus_per_task),
                                fmt::format("--signal=B:TERM@{}", o.signal_seconds)};
  if (!o.partition.empty()) s.push_back("--partition=" + o.partition);
  if (!o.time.empty()) s.push_back("--time=" + o.time);
  if (!o.mem.empty()) s.push_back("--mem=" + o.mem);
  for (const std::string& a : o.sbatch_args) s.push_back(a);
  return s;
}

std::string render_command(const std::string& theia, const std::string& scene, const std::string& output,
                           const std::string& checkpoint, const std::vector<std::string>& args,
                           const SampleRange* range) {
  std::vector<std::string> w = {theia, "render", scene, "-o", output, "--checkpoint-dir", checkpoint};
  if (range) w.insert(w.end(), {"--sample-range", fmt::format("{}:{}", range->begin, range->end)});
  w.insert(w.end(), args.begin(), args.end());
  return join_quoted(w);
}

std::string frame_name(const std::string& scene) { return fs::path(scene).stem().string(); }

// Runs a command, returns its standard output; throws with its exit status.
std::string run_capture(const std::string& command) {
  FILE* p = popen(command.c_str(), "r");
  if (!p) throw_error("cannot run: {}", command);
  std::string out;
  char buf[4096];
  for (size_t n; (n = fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
  int status = pclose(p);
  if (status != 0) throw_error("'{}' failed (status {}): {}", command, status, out);
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

nlohmann::json read_manifest(const std::string& dir) {
  const std::string path = (fs::path(dir) / "farm.json").string();
  std::ifstream f(path);
  if (!f) throw_error("{}: no farm here (no farm.json; `theia farm submit -d {}` writes it)", path, dir);
  try {
    return nlohmann::json::parse(f);
  } catch (const nlohmann::json::exception& e) {
    throw_error("{}: not valid JSON: {}", path, e.what());
  }
}

}  // namespace

std::vector<std::string> split_words(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

void check(const FarmSubmitOptions& o) {
  if (o.scenes.empty() == o.pattern.empty())
    throw_error("farm submit: give the scene files or --pattern with --frames (one of the two)");
  if (!o.pattern.empty() && o.frames.empty()) throw_error("farm submit: --pattern needs --frames A-B[:STEP]");
  if (o.dir.empty()) throw_error("farm submit: -d/--dir (the output directory) is required");
  if (o.split < 1) throw_error("farm submit: --split must be at least 1, got {}", o.split);
  if (o.spp < 0) throw_error("farm submit: --spp must be positive, got {}", o.spp);
  if (o.split > 1 && o.spp == 0) throw_error("farm submit: --split needs --spp (the samples the parts divide)");
  if (o.split > 1 && o.split > o.spp)
    throw_error("farm submit: --split {} is more parts than --spp {} samples", o.split, o.spp);
  if (o.cpus_per_task < 1) throw_error("farm submit: --cpus-per-task must be at least 1, got {}", o.cpus_per_task);
  if (o.signal_seconds < 1) throw_error("farm submit: --signal-seconds must be at least 1, got {}", o.signal_seconds);
  for (const std::string& w : split_words(o.render_options))
    for (const char* own : {"-o", "--output", "--checkpoint-dir", "--threads", "--spp", "--sample-range", "--log"})
      if (w == own || w.rfind(std::string(own) + "=", 0) == 0)
        throw_error("farm submit: --render-options may not set {}: the farm sets it for each task{}", own,
                    std::string(own) == "--spp" ? " (use farm submit --spp)" : "");
}

std::vector<std::string> expand_frame_pattern(const std::string& pattern, const std::string& frames) {
  const size_t dash = frames.find('-', 1), colon = frames.find(':');
  if (dash == std::string::npos) throw_error("--frames {}: expected A-B[:STEP]", frames);
  const int a = parse_int(frames.substr(0, dash), "--frames " + frames);
  const int b = parse_int(frames.substr(dash + 1, colon == std::string::npos ? std::string::npos : colon - dash - 1),
                          "--frames " + frames);
  const int step = colon == std::string::npos ? 1 : parse_int(frames.substr(colon + 1), "--frames " + frames);
  if (b < a || step < 1) throw_error("--frames {}: expected A <= B and STEP >= 1", frames);
  const size_t pct = pattern.find('%');
  if (pct == std::string::npos || pattern.find('%', pct + 1) != std::string::npos ||
      pattern.find('d', pct) == std::string::npos)
    throw_error("--pattern {}: expected one %d or %0Nd where the frame number goes", pattern);
  const size_t d = pattern.find('d', pct);
  const std::string spec = pattern.substr(pct + 1, d - pct - 1);  // "" or "04"
  for (char c : spec)
    if (c < '0' || c > '9') throw_error("--pattern {}: expected %d or %0Nd", pattern);
  const int width = spec.empty() ? 0 : parse_int(spec, "--pattern " + pattern);
  std::vector<std::string> scenes;
  for (int f = a; f <= b; f += step)
    scenes.push_back(pattern.substr(0, pct) + fmt::format("{:0{}d}", f, width) + pattern.substr(d + 1));
  return scenes;
}

std::string batch_script(const BatchJob& job) {
  std::string s = "#!/bin/bash\n";
  s += fmt::format("#SBATCH --job-name={}\n", job.name);
  if (job.commands.size() > 1) s += fmt::format("#SBATCH --array=0-{}\n", job.commands.size() - 1);
  s += fmt::format("#SBATCH --output={}\n#SBATCH --open-mode=append\n", job.output);
  if (job.requeue) s += "#SBATCH --requeue\n";
  for (const std::string& o : job.sbatch) s += "#SBATCH " + o + "\n";
  s += "set -u\ntask=${SLURM_ARRAY_TASK_ID:-0}\n";
  for (size_t k = 0; k < job.commands.size(); ++k)
    s += fmt::format("task_{}() {{ exec {}; }}\n", k, job.commands[k]);
  s += R"SH(echo "farm: start task=$task restart=${SLURM_RESTART_COUNT:-0} job=${SLURM_JOB_ID:-none} time=$(date +%s) host=$(hostname)"
# The render runs in the background so that this shell can pass on the
# SIGTERM Slurm sends it (--signal=B:TERM@N before the time limit; scancel -b).
"task_$task" &
pid=$!
trap 'kill -TERM "$pid" 2>/dev/null' TERM INT
while :; do
  wait "$pid"; rc=$?
  kill -0 "$pid" 2>/dev/null || break
done
wait "$pid" 2>/dev/null; last=$?
[ "$last" -ne 127 ] && rc=$last
echo "farm: end task=$task exit=$rc time=$(date +%s)"
)SH";
  if (job.requeue)
    s += R"SH(if [ "$rc" -eq 75 ]; then
  # Stopped with its state checkpointed: requeue this task alone.  An array
  # task is ARRAYID_INDEX: the array's own id would requeue every task.
  if [ -n "${SLURM_ARRAY_JOB_ID:-}" ]; then me=${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}; else me=$SLURM_JOB_ID; fi
  echo "farm: requeue task=$task job=$me"
  scontrol requeue "$me" && exit 0
fi
)SH";
  s += "exit \"$rc\"\n";
  return s;
}

FarmPlan plan_farm(const FarmSubmitOptions& o) {
  check(o);
  const std::vector<std::string> scenes = o.scenes.empty() ? expand_frame_pattern(o.pattern, o.frames) : o.scenes;
  const fs::path dir = fs::absolute(o.dir);
  const std::string theia = o.theia.empty() ? this_binary() : o.theia;
  const std::vector<std::string> args = common_render_args(o);
  const std::vector<std::string> sbatch = sbatch_options(o);
  FarmPlan plan;
  nlohmann::json& m = plan.manifest;
  m = {{"dir", dir.string()}, {"theia", theia}, {"split", o.split}, {"spp", o.spp}, {"render_args", args},
       {"frames", nlohmann::json::array()}};
  std::set<std::string> names;
  BatchJob sequence{"theia-frames", {}, (dir / "logs" / "frame-%a.out").string(), sbatch};
  for (size_t f = 0; f < scenes.size(); ++f) {
    const std::string scene = fs::absolute(scenes[f]).string(), name = frame_name(scene);
    if (!names.insert(name).second) throw_error("farm submit: two frames are named {} ({})", name, scene);
    const std::string output = (dir / "frames" / (name + ".exr")).string();
    nlohmann::json frame = {{"name", name}, {"scene", scene}, {"output", output}};
    if (o.split == 1) {
      const std::string ck = (dir / "checkpoints" / name).string();
      sequence.commands.push_back(render_command(theia, scene, output, ck, args, nullptr));
      frame["tasks"] = {{{"log", (dir / "logs" / fmt::format("frame-{}.out", f)).string()},
                         {"checkpoint", ck},
                         {"output", output}}};
      m["frames"].push_back(frame);
      continue;
    }
    BatchJob parts{"theia-" + name + "-parts", {}, (dir / "logs" / (name + ".part-%a.out")).string(), sbatch};
    std::vector<std::string> merge = {theia, "merge"};
    frame["tasks"] = nlohmann::json::array();
    const std::vector<SampleRange> ranges = split_ranges(o.spp, o.split);
    for (size_t k = 0; k < ranges.size(); ++k) {
      const std::string part = (dir / "parts" / fmt::format("{}.part-{}.exr", name, k)).string();
      const std::string ck = (dir / "checkpoints" / fmt::format("{}.part-{}", name, k)).string();
      parts.commands.push_back(render_command(theia, scene, part, ck, args, &ranges[k]));
      merge.push_back(part);
      frame["tasks"].push_back({{"log", (dir / "logs" / fmt::format("{}.part-{}.out", name, k)).string()},
                                {"checkpoint", ck},
                                {"output", part},
                                {"sample_range", {ranges[k].begin, ranges[k].end}}});
    }
    merge.insert(merge.end(), {"-o", output});
    frame["merge_log"] = (dir / "logs" / (name + ".merge.out")).string();
    plan.jobs.push_back(std::move(parts));
    plan.jobs.push_back({"theia-" + name + "-merge", {join_quoted(merge)}, frame["merge_log"], sbatch, false});
    m["frames"].push_back(frame);
  }
  if (o.split == 1) plan.jobs.push_back(std::move(sequence));
  return plan;
}

int run_farm_submit(const FarmSubmitOptions& o) {
  FarmPlan plan = plan_farm(o);
  const fs::path dir = plan.manifest["dir"].get<std::string>();
  nlohmann::json jobs = nlohmann::json::array();
  std::string previous;  // a merge job depends on the parts job before it
  for (const BatchJob& job : plan.jobs) {
    const bool is_merge = job.name.size() > 6 && job.name.substr(job.name.size() - 6) == "-merge";
    const std::string script = batch_script(job);
    const std::string path = (dir / "jobs" / (job.name + ".sbatch")).string();
    if (o.dry_run) {
      fmt::print("# {}{}\n{}\n", path, is_merge ? " (submitted with --dependency=afterok:<the parts job>)" : "",
                 script);
      continue;
    }
    for (const char* sub : {"jobs", "frames", "parts", "checkpoints", "logs"}) fs::create_directories(dir / sub);
    write_text_atomically(path, script);
    std::string command = "sbatch --parsable";
    if (is_merge) command += " --kill-on-invalid-dep=yes --dependency=afterok:" + previous;
    const std::string id = run_capture(command + " " + quote(path));
    previous = id.substr(0, id.find(';'));  // --parsable: ID or ID;CLUSTER
    jobs.push_back({{"name", job.name}, {"id", previous}, {"script", path}, {"tasks", job.commands.size()}});
    log_info("submitted {} ({} task{}): job {}", job.name, job.commands.size(), job.commands.size() == 1 ? "" : "s",
             previous);
  }
  if (o.dry_run) return 0;
  plan.manifest["jobs"] = jobs;
  write_text_atomically((dir / "farm.json").string(), plan.manifest.dump(2) + "\n");
  return 0;
}

namespace {

// One task as its log (the wrapper's start and end lines) tells it.
struct TaskState {
  int starts = 0, requeues = 0;
  bool running = false;
  int last_exit = -1;  // -1: none yet
  double seconds = 0.0;
};

long field(const std::string& line, const std::string& key) {
  const size_t at = line.find(" " + key + "=");
  if (at == std::string::npos) return -1;
  return std::strtol(line.c_str() + at + key.size() + 2, nullptr, 10);
}

TaskState read_task_log(const std::string& path) {
  TaskState t;
  std::ifstream f(path);
  long started = 0;
  const long now = long(std::time(nullptr));
  int restarts = 0;
  for (std::string line; std::getline(f, line);) {
    if (line.rfind("farm: start ", 0) == 0) {
      if (t.running) {  // killed without an end line (SIGKILL): count it until this start
        t.seconds += double(field(line, "time") - started);
        ++t.requeues;
      }
      ++t.starts;
      t.running = true;
      started = field(line, "time");
      restarts = std::max(restarts, int(field(line, "restart")));
    } else if (line.rfind("farm: end ", 0) == 0 && t.running) {
      t.running = false;
      t.last_exit = int(field(line, "exit"));
      t.seconds += double(field(line, "time") - started);
      if (t.last_exit == 75) ++t.requeues;
    }
  }
  if (t.running) t.seconds += double(now - started);
  t.requeues = std::max(t.requeues, restarts);
  return t;
}

std::string task_state_name(const TaskState& t) {
  if (t.starts == 0) return "pending";
  if (t.running) return "running";
  if (t.last_exit == 0) return "done";
  if (t.last_exit == 75) return "requeued";
  return fmt::format("failed (exit {})", t.last_exit);
}

nlohmann::json read_json_or_null(const std::string& path) {
  std::ifstream f(path);
  if (!f) return nullptr;
  try {
    return nlohmann::json::parse(f);
  } catch (const nlohmann::json::exception&) {
    return nullptr;
  }
}

// Samples per pixel a render reached: its log when it finished, else its newest checkpoint.
uint32_t spp_reached(const std::string& output, const std::string& checkpoint_dir) {
  const nlohmann::json log = read_json_or_null(fs::path(output).replace_extension(".json").string());
  if (log.is_object() && log.contains("scheduler"))
    return log["scheduler"]["spp_per_pixel"].value("min", uint32_t(0));
  try {
    if (auto c = read_latest_checkpoint(checkpoint_dir)) return checkpoint_spp(*c).first;
  } catch (const Error&) {
  }
  return 0;
}

struct FrameStatus {
  std::string state;
  int requeues = 0;
  uint32_t spp = 0;
  double seconds = 0.0;
};

FrameStatus frame_status(const nlohmann::json& frame) {
  FrameStatus s;
  const std::string output = frame["output"];
  const bool split = frame.contains("merge_log");
  std::vector<std::string> states;
  for (const nlohmann::json& task : frame["tasks"]) {
    TaskState t = read_task_log(task["log"]);
    s.requeues += t.requeues;
    s.seconds += t.seconds;
    states.push_back(task_state_name(t));
    s.spp += spp_reached(task["output"], task["checkpoint"]);  // a split frame's parts add up
  }
  const bool have_output = fs::exists(output) && fs::exists(fs::path(output).replace_extension(".json"));
  auto any = [&](const std::string& prefix) {
    for (const std::string& st : states)
      if (st.rfind(prefix, 0) == 0) return true;
    return false;
  };
  if (have_output)
    s.state = "done";
  else if (any("failed"))
    s.state = "failed";
  else if (any("running"))
    s.state = "running";
  else if (any("requeued"))
    s.state = "requeued";
  else if (split && !any("pending")) {
    TaskState m = read_task_log(frame["merge_log"]);
    s.state = m.starts == 0 ? "merging (pending)" : "merge " + task_state_name(m);
  } else
    s.state = "pending";
  return s;
}

}  // namespace

int run_farm_status(const std::string& dir) {
  const nlohmann::json m = read_manifest(dir);
  fmt::print("{:<24} {:<18} {:>8} {:>8} {:>10}\n", "frame", "state", "requeued", "spp", "seconds");
  int done = 0;
  for (const nlohmann::json& frame : m["frames"]) {
    const FrameStatus s = frame_status(frame);
    done += s.state == "done";
    fmt::print("{:<24} {:<18} {:>8} {:>8} {:>10.1f}\n", frame["name"].get<std::string>(), s.state, s.requeues, s.spp,
               s.seconds);
  }
  fmt::print("{} of {} frames done\n", done, m["frames"].size());
  return 0;
}

int run_farm_collect(const std::string& dir) {
  const nlohmann::json m = read_manifest(dir);
  std::vector<std::string> problems;
  for (const nlohmann::json& frame : m["frames"]) {
    const std::string output = frame["output"], log_path = fs::path(output).replace_extension(".json").string();
    const std::string name = frame["name"];
    if (!fs::exists(output)) {
      problems.push_back(fmt::format("{}: missing {}", name, output));
      continue;
    }
    const nlohmann::json log = read_json_or_null(log_path);
    if (!log.is_object() || !log.contains("scheduler")) {
      problems.push_back(fmt::format("{}: {} has no complete log {}", name, output, log_path));
      continue;
    }
    const uint32_t want = log["options"].value("spp", uint32_t(0));
    const auto& spp = log["scheduler"]["spp_per_pixel"];
    if (spp.value("min", uint32_t(0)) != want || spp.value("max", uint32_t(0)) != want) {
      problems.push_back(fmt::format("{}: incomplete, {}-{} of {} spp", name, spp.value("min", 0), spp.value("max", 0),
                                     want));
      continue;
    }
    try {
      const ImageBuffer img = read_image_file(output);
      const auto& res = log["resolution"];
      if (img.width != res[0].get<int>() || img.height != res[1].get<int>())
        throw_error("{}x{}, its log says {}x{}", img.width, img.height, res[0].get<int>(), res[1].get<int>());
    } catch (const Error& e) {
      problems.push_back(fmt::format("{}: {} unreadable: {}", name, output, e.what()));
      continue;
    }
    fmt::print("{}: {} ({} spp)\n", name, output, want);
  }
  for (const std::string& p : problems) fmt::print("NOT COMPLETE {}\n", p);
  fmt::print("{} of {} frames complete\n", m["frames"].size() - problems.size(), m["frames"].size());
  return problems.empty() ? 0 : 1;
}

}  // namespace theia
