#pragma once

// Progress display for long work: a redrawn bar on a terminal, plain lines otherwise
// (logs and CI output stay readable).

#include <chrono>
#include <cstdio>
#include <string>

namespace tessera {

// "1m05s", "2h03m10s", "4.2s".
std::string FormatDuration(double seconds);

class ProgressBar {
  public:
    // `unit` names what is counted: "tiles", "batches".
    ProgressBar(std::string label, int total, std::FILE* out = stderr, std::string unit = "tiles");
    void Update(int done);
    void Finish();

  private:
    std::string label_;
    std::string unit_;
    int total_;
    std::FILE* out_;
    bool tty_;
    int last_percent_printed_ = -1;
    std::chrono::steady_clock::time_point start_;
};

}  // namespace tessera
