#pragma once

// The worker's recent log lines, kept in memory so that a failed task's report carries
// what was logged while it ran (FailTaskRequest.log_tail): the coordinator keeps it with
// the failure, so the user reads it without logging into the worker's machine.
//
// Tasks run side by side, so the lines of a task are told apart by where they come from:
// those its render thread logged since it started the task, and those of any thread that
// name the task (a heartbeat's warning, a retried fetch).

#include <spdlog/common.h>
#include <spdlog/sinks/ringbuffer_sink.h>

#include <cstddef>
#include <memory>
#include <string>

namespace tessera {

class LogTail {
  public:
    // What one task's tail may hold (FailTaskRequest.log_tail is at most 8 KiB).
    static constexpr size_t kMaxLines = 40;
    static constexpr size_t kMaxBytes = 8 << 10;

    // Keeps the last `capacity` lines of the whole process.
    explicit LogTail(size_t capacity = 1000);

    // The sink that feeds it: add it to a logger.
    std::shared_ptr<spdlog::sinks::sink> Sink() const { return ring_; }

    // The lines logged at or after `since` by the thread `thread` (ThisThread() of the
    // thread that ran the task) or that contain `mention`: the newest of them, at most
    // kMaxLines and kMaxBytes in all, oldest first, each ending in a newline. A line
    // longer than the whole budget is cut.
    std::string Lines(spdlog::log_clock::time_point since, size_t thread,
                      const std::string& mention) const;

    // The calling thread's id as log messages carry it.
    static size_t ThisThread();

  private:
    std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> ring_;
};

// The process's LogTail, added to spdlog's default logger unless it is there already
// (a later SetUpLogging replaces that logger: call this again after it). The default
// logger is replaced by a copy with the extra sink, never changed in place, and the old one
// is kept alive; still, spdlog does not allow replacing it while another thread logs
// through it, so call this before other threads log.
LogTail& InstallLogTail();

}  // namespace tessera
