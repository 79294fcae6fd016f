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
    ProgressBar(std::string label, int total, std::FILE* out = stderr);
    void Update(int done);
    void Finish();

  private:
    std::string label_;
    int total_;
    std::FILE* out_;
    bool tty_;
    int last_percent_printed_ = -1;
    std::chrono::steady_clock::time_point start_;
};

}  // namespace tessera
