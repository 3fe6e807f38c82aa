#include "mcslam/app/bench/task.hpp"

#include <unistd.h>

#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "mcslam/app/bench/process.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"

namespace mcslam::app::bench {
namespace fs = std::filesystem;

namespace {

double unix_now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

nlohmann::json record_json(const TaskRecord& r) {
  return {{"started", r.started},     {"exit_code", r.exit_code}, {"signal", r.signal},
          {"timed_out", r.timed_out}, {"wall_s", r.wall_s},       {"start_unix", r.start_unix},
          {"end_unix", r.end_unix},   {"host", r.host},           {"cpus", r.cpus},
          {"slurm_job", r.slurm_job}, {"error", r.error},         {"ok", r.ok()}};
}

TaskRecord record_from(const nlohmann::json& j) {
  TaskRecord r;
  r.started = j.at("started").get<bool>();
  r.exit_code = j.at("exit_code").get<int>();
  r.signal = j.at("signal").get<int>();
  r.timed_out = j.at("timed_out").get<bool>();
  r.wall_s = j.at("wall_s").get<double>();
  r.start_unix = j.at("start_unix").get<double>();
  r.end_unix = j.at("end_unix").get<double>();
  r.host = j.at("host").get<std::string>();
  r.cpus = j.at("cpus").get<int>();
  r.slurm_job = j.at("slurm_job").get<std::string>();
  r.error = j.at("error").get<std::string>();
  return r;
}

}  // namespace

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

std::string host_name() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0) return "unknown";
  return name;
}

std::string run_directory(const std::string& dir, const PlannedRun& run) {
  return (fs::path(dir) / run.folder()).string();
}

std::string run_log(const std::string& dir, const PlannedRun& run) {
  return run_directory(dir, run) + ".log";
}

std::string task_record_path(const std::string& dir, const PlannedRun& run) {
  return run_directory(dir, run) + ".task.json";
}

TaskRecord execute_run(const std::string& dir, const PlannedRun& run, const std::string& executable,
                       double timeout_s, const std::string& slurm_job) {
  const std::string folder = run_directory(dir, run), log = run_log(dir, run),
                    record_path = task_record_path(dir, run);
  std::error_code ec;
  fs::remove(record_path, ec);
  fs::remove_all(folder, ec);
  fs::remove(log, ec);
  io::ensure_directory(folder);

  TaskRecord record;
  record.host = host_name();
  record.cpus = static_cast<int>(std::thread::hardware_concurrency());
  record.slurm_job = slurm_job;
  record.start_unix = unix_now();
  const ProcessResult process = run_process(executable, run.arguments, log, timeout_s);
  record.end_unix = unix_now();
  record.started = process.started;
  record.exit_code = process.exit_code;
  record.signal = process.signal;
  record.timed_out = process.timed_out;
  record.wall_s = process.wall_s;
  if (!process.ok()) record.error = failure_text(process, log, timeout_s);
  io::write_file_atomic(record_path, record_json(record).dump(1) + "\n");
  return record;
}

std::optional<TaskRecord> read_task_record(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  try {
    return record_from(nlohmann::json::parse(in));
  } catch (const nlohmann::json::exception& e) {
    TaskRecord broken;
    broken.error = file_error(path, std::string("not a task record: ") + e.what());
    return broken;
  }
}

}  // namespace mcslam::app::bench
