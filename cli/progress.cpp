#include "progress.h"

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

ProgressBar::ProgressBar(std::string label, int total, std::FILE* out, std::string unit)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(std::max(total, 1)),
      out_(out),
      tty_(isatty(fileno(out)) != 0),
      start_(std::chrono::steady_clock::now()) {}

void ProgressBar::Update(int done) {
    double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    double frac = std::clamp(double(done) / total_, 0.0, 1.0);
    std::string eta = done > 0 ? FormatDuration(elapsed / frac - elapsed) : "?";
    int percent = static_cast<int>(frac * 100);
    if (tty_) {
        constexpr int kWidth = 30;
        int filled = static_cast<int>(frac * kWidth);
        std::string bar(filled, '#');
        bar.append(kWidth - filled, '-');
        std::fprintf(out_, "\r%s [%s] %d/%d %s %3d%%  elapsed %s  ETA %s   ", label_.c_str(),
                     bar.c_str(), done, total_, unit_.c_str(), percent,
                     FormatDuration(elapsed).c_str(), eta.c_str());
        std::fflush(out_);
    } else if (percent / 10 != last_percent_printed_ / 10 || done == total_) {
        last_percent_printed_ = percent;
        std::fprintf(out_, "%s: %d/%d %s (%d%%), elapsed %s, ETA %s\n", label_.c_str(), done,
                     total_, unit_.c_str(), percent, FormatDuration(elapsed).c_str(), eta.c_str());
        std::fflush(out_);
    }
}

void ProgressBar::Finish() {
    if (tty_) std::fprintf(out_, "\n");
}

}  // namespace tessera
