#pragma once

// Child processes that `tessera farm` starts and must always stop again: each runs in a
// process group of its own (so that Ctrl-C on the terminal reaches only `tessera`, which
// then shuts the children down in order) and dies with its parent (PR_SET_PDEATHSIG), so
// that not even a killed `tessera` leaves a coordinator or worker behind.

#include <sys/types.h>

#include <chrono>
#include <string>
#include <vector>

namespace tessera {

class ChildProcess {
  public:
    // Starts `argv[0]` with `argv`, its stdout and stderr appended to `log_path`.
    // Throws std::runtime_error if it cannot be started.
    ChildProcess(const std::vector<std::string>& argv, const std::string& log_path);
    ~ChildProcess();
    ChildProcess(const ChildProcess&) = delete;
    ChildProcess& operator=(const ChildProcess&) = delete;

    pid_t Pid() const { return pid_; }
    const std::string& Name() const { return name_; }
    const std::string& LogPath() const { return log_path_; }
    // Reaps the child if it has exited; true while it runs.
    bool Running();
    // "exited with status 1", "killed by signal 9" (once it has exited).
    std::string ExitText() const;
    // Sends SIGTERM to the child's group.
    void Terminate();
    // Waits up to `timeout` for the child to exit after Terminate(), then kills its
    // group with SIGKILL and waits for it.
    void Wait(std::chrono::milliseconds timeout);

  private:
    std::string name_;
    std::string log_path_;
    pid_t pid_ = -1;
    bool exited_ = false;
    int wait_status_ = 0;
};

// Stops children in order: SIGTERM to all, then up to `timeout` for them to exit, then
// SIGKILL for the rest.
void StopAll(const std::vector<ChildProcess*>& children, std::chrono::milliseconds timeout);

// The path of an executable: `<dir of this program>/<subdir>/<name>`, then
// `<dir of this program>/<name>`, then the PATH. Empty if none is found.
std::string FindSiblingProgram(const std::string& subdir, const std::string& name);

}  // namespace tessera
