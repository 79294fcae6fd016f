#include "child_process.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <thread>

namespace tessera {

namespace fs = std::filesystem;

ChildProcess::ChildProcess(const std::vector<std::string>& argv, const std::string& log_path)
    : name_(fs::path(argv.at(0)).filename().string()), log_path_(log_path) {
    // Everything the child needs is prepared before fork(): between fork and exec only
    // async-signal-safe calls are allowed (other threads may hold locks).
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    int log_fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (log_fd < 0)
        throw std::runtime_error("cannot open " + log_path + ": " + std::strerror(errno));
    int null_fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
    // exec failure travels back through a close-on-exec pipe: EOF means exec succeeded.
    int report[2];
    if (null_fd < 0 || ::pipe2(report, O_CLOEXEC) != 0) {
        ::close(log_fd);
        if (null_fd >= 0) ::close(null_fd);
        throw std::runtime_error(std::string("cannot start a process: ") + std::strerror(errno));
    }
    pid_t parent = ::getpid();
    pid_t pid = ::fork();
    if (pid == 0) {
        ::setpgid(0, 0);
        ::prctl(PR_SET_PDEATHSIG, SIGTERM);
        if (::getppid() != parent) ::_exit(127);  // the parent died before prctl
        sigset_t none;
        sigemptyset(&none);
        ::sigprocmask(SIG_SETMASK, &none, nullptr);
        ::signal(SIGINT, SIG_DFL);
        ::signal(SIGTERM, SIG_DFL);
        ::signal(SIGPIPE, SIG_DFL);
        ::dup2(null_fd, STDIN_FILENO);
        ::dup2(log_fd, STDOUT_FILENO);
        ::dup2(log_fd, STDERR_FILENO);
        ::execv(args[0], args.data());
        int err = errno;
        [[maybe_unused]] ssize_t n = ::write(report[1], &err, sizeof err);
        ::_exit(127);
    }
    int fork_errno = errno;
    ::close(log_fd);
    ::close(null_fd);
    ::close(report[1]);
    if (pid < 0) {
        ::close(report[0]);
        throw std::runtime_error("cannot fork: " + std::string(std::strerror(fork_errno)));
    }
    ::setpgid(pid, pid);  // also here, so that the group exists whoever runs first
    pid_ = pid;
    int err = 0;
    ssize_t n;
    do {
        n = ::read(report[0], &err, sizeof err);
    } while (n < 0 && errno == EINTR);
    ::close(report[0]);
    if (n == sizeof err) {
        Wait(std::chrono::milliseconds(1000));
        throw std::runtime_error("cannot run " + argv[0] + ": " + std::strerror(err));
    }
}

ChildProcess::~ChildProcess() {
    if (!Running()) return;
    Terminate();
    Wait(std::chrono::milliseconds(5000));
}

bool ChildProcess::Running() {
    if (exited_ || pid_ <= 0) return false;
    int status = 0;
    pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_ || (r < 0 && errno == ECHILD)) {
        exited_ = true;
        wait_status_ = status;
    }
    return !exited_;
}

std::string ChildProcess::ExitText() const {
    if (!exited_) return "running";
    if (WIFEXITED(wait_status_))
        return "exited with status " + std::to_string(WEXITSTATUS(wait_status_));
    if (WIFSIGNALED(wait_status_))
        return "killed by signal " + std::to_string(WTERMSIG(wait_status_)) + " (" +
               strsignal(WTERMSIG(wait_status_)) + ")";
    return "ended";
}

void ChildProcess::Terminate() {
    if (Running()) ::kill(-pid_, SIGTERM);
}

void ChildProcess::Wait(std::chrono::milliseconds timeout) {
    auto deadline = std::chrono::steady_clock::now() + timeout;
    while (Running() && std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (Running()) {
        ::kill(-pid_, SIGKILL);
        ::kill(pid_, SIGKILL);
        int status = 0;
        while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
        }
        exited_ = true;
        wait_status_ = status;
    }
}

void StopAll(const std::vector<ChildProcess*>& children, std::chrono::milliseconds timeout) {
    for (ChildProcess* c : children) c->Terminate();
    auto deadline = std::chrono::steady_clock::now() + timeout;
    for (ChildProcess* c : children) {
        auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        c->Wait(std::max(left, std::chrono::milliseconds(0)));
    }
}

std::string FindSiblingProgram(const std::string& subdir, const std::string& name) {
    std::error_code ec;
    fs::path self = fs::read_symlink("/proc/self/exe", ec);
    auto executable = [](const fs::path& p) {
        std::error_code ec;
        return !p.empty() && ::access(p.c_str(), X_OK) == 0 && fs::is_regular_file(p, ec);
    };
    if (!ec) {
        fs::path dir = self.parent_path();
        for (const fs::path& p : {dir / subdir / name, dir / name})
            if (executable(p)) return p.lexically_normal().string();
    }
    const char* path = std::getenv("PATH");
    std::string dirs = path ? path : "";
    size_t start = 0;
    while (start <= dirs.size()) {
        size_t end = dirs.find(':', start);
        if (end == std::string::npos) end = dirs.size();
        std::string dir = dirs.substr(start, end - start);
        if (!dir.empty() && executable(fs::path(dir) / name))
            return (fs::path(dir) / name).string();
        start = end + 1;
    }
    return {};
}

}  // namespace tessera
