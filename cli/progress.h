#pragma once

// Progress display for long work: a redrawn bar on a terminal, plain lines otherwise
// (logs and CI output stay readable). On a terminal the line fits its width, read again at
// every redraw (so a resized window gets a line of its new width), and is redrawn at least
// twice a second by a ticker thread: elapsed time and rates never freeze.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace tessera {

// "1m05s", "2h03m10s", "4.2s".
std::string FormatDuration(double seconds);
// "950", "12.3k", "4.56M", "1.20G".
std::string FormatCount(double n);
// Columns of the terminal behind `out`; 80 when it is not a terminal or does not say.
int TerminalColumns(std::FILE* out);
// "head [#####-----] tail" in at most `columns` characters: the bar gets what the text
// leaves (none under 10 columns), and the tail is cut last.
std::string FitBarLine(const std::string& head, double fraction, const std::string& tail,
                       int columns);

// Calls `tick` every `period` on its own thread until destroyed.
class Ticker {
  public:
    Ticker(std::function<void()> tick, std::chrono::milliseconds period);
    ~Ticker();
    Ticker(const Ticker&) = delete;
    Ticker& operator=(const Ticker&) = delete;

  private:
    std::mutex mu_;
    std::condition_variable cv_;
    bool stop_ = false;
    std::thread thread_;
};

class ProgressBar {
  public:
    // `unit` names what is counted: "tiles", "batches". `samples`, when positive, is the
    // camera samples the whole count stands for: the line then shows samples/s.
    ProgressBar(std::string label, int total, std::FILE* out = stderr, std::string unit = "tiles",
                double samples = 0);
    ~ProgressBar();
    void Update(int done);
    void Finish();

  private:
    void DrawLocked();

    std::string label_;
    std::string unit_;
    int total_;
    double samples_;
    std::FILE* out_;
    bool tty_;
    int done_ = 0;
    bool finished_ = false;
    int last_percent_printed_ = -1;
    std::chrono::steady_clock::time_point start_;
    std::mutex mu_;
    std::unique_ptr<Ticker> ticker_;  // last: stopped before the rest goes
};

}  // namespace tessera
