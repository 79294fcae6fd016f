#include "progress.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>

namespace tessera {

std::string FormatDuration(double s) {
    int total = static_cast<int>(s + 0.5);
    char buf[32];
    if (total >= 3600)
        std::snprintf(buf, sizeof buf, "%dh%02dm%02ds", total / 3600, total / 60 % 60, total % 60);
    else if (total >= 60)
        std::snprintf(buf, sizeof buf, "%dm%02ds", total / 60, total % 60);
    else
        std::snprintf(buf, sizeof buf, "%.1fs", s);
    return buf;
}

std::string FormatCount(double n) {
    char buf[32];
    if (n >= 1e9)
        std::snprintf(buf, sizeof buf, "%.2fG", n / 1e9);
    else if (n >= 1e6)
        std::snprintf(buf, sizeof buf, "%.2fM", n / 1e6);
    else if (n >= 1e3)
        std::snprintf(buf, sizeof buf, "%.1fk", n / 1e3);
    else
        std::snprintf(buf, sizeof buf, "%.0f", n);
    return buf;
}

int TerminalColumns(std::FILE* out) {
    winsize size{};
    if (::ioctl(fileno(out), TIOCGWINSZ, &size) == 0 && size.ws_col > 0) return size.ws_col;
    return 80;
}

std::string FitBarLine(const std::string& head, double fraction, const std::string& tail,
                       int columns) {
    // One column spare: writing the last one makes some terminals wrap.
    const int room = std::max(columns - 1, 1);
    const int text = static_cast<int>(head.size() + tail.size()) + 2;
    const int bar = std::min(40, room - text - 2);
    std::string line = head + " ";
    if (bar >= 10) {
        const int filled = static_cast<int>(std::clamp(fraction, 0.0, 1.0) * bar);
        line += "[" + std::string(filled, '#') + std::string(bar - filled, '-') + "] ";
    }
    line += tail;
    if (static_cast<int>(line.size()) > room) line.resize(room);
    return line;
}

Ticker::Ticker(std::function<void()> tick, std::chrono::milliseconds period)
    : thread_([this, tick = std::move(tick), period] {
          std::unique_lock lock(mu_);
          while (!cv_.wait_for(lock, period, [this] { return stop_; })) {
              lock.unlock();
              tick();
              lock.lock();
          }
      }) {}

Ticker::~Ticker() {
    {
        std::lock_guard lock(mu_);
        stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
}

ProgressBar::ProgressBar(std::string label, int total, std::FILE* out, std::string unit,
                         double samples)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(std::max(total, 1)),
      samples_(samples),
      out_(out),
      tty_(isatty(fileno(out)) != 0),
      start_(std::chrono::steady_clock::now()) {
    if (tty_)
        ticker_ = std::make_unique<Ticker>(
            [this] {
                std::lock_guard lock(mu_);
                if (!finished_) DrawLocked();
            },
            std::chrono::milliseconds(500));
}

ProgressBar::~ProgressBar() { ticker_.reset(); }

void ProgressBar::Update(int done) {
    std::lock_guard lock(mu_);
    done_ = done;
    DrawLocked();
}

void ProgressBar::DrawLocked() {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double frac = std::clamp(double(done_) / total_, 0.0, 1.0);
    const std::string eta = done_ > 0 ? FormatDuration(elapsed / frac - elapsed) : "?";
    const int percent = static_cast<int>(frac * 100);
    std::string rate;
    if (samples_ > 0 && elapsed > 0.5)  // a rate over a shorter time says little
        rate = ", " + FormatCount(frac * samples_ / elapsed) + " samples/s";
    if (tty_) {
        char tail[160];
        // What matters most first: a narrow terminal cuts the end.
        std::snprintf(tail, sizeof tail, "%d/%d %s %3d%%, ETA %s%s, elapsed %s", done_, total_,
                      unit_.c_str(), percent, eta.c_str(), rate.c_str(),
                      FormatDuration(elapsed).c_str());
        std::fprintf(out_, "\r\033[K%s",
                     FitBarLine(label_, frac, tail, TerminalColumns(out_)).c_str());
        std::fflush(out_);
    } else if (percent / 10 != last_percent_printed_ / 10 || done_ == total_) {
        last_percent_printed_ = percent;
        std::fprintf(out_, "%s: %d/%d %s (%d%%)%s, elapsed %s, ETA %s\n", label_.c_str(), done_,
                     total_, unit_.c_str(), percent, rate.c_str(), FormatDuration(elapsed).c_str(),
                     eta.c_str());
        std::fflush(out_);
    }
}

void ProgressBar::Finish() {
    ticker_.reset();
    std::lock_guard lock(mu_);
    if (tty_ && !finished_) std::fprintf(out_, "\n");
    finished_ = true;
}

}  // namespace tessera
