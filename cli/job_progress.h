#pragma once

#include "progress.h"

// Live progress of a farm job: tasks, frames, the stage under way ("photons 12/16",
// "irradiance pass 2/3 (40/64)", "render 130/256"), elapsed time and ETA, as a redrawn bar on
// a terminal and as plain lines otherwise. Unlike ProgressBar (one local render, counted
// from zero) a job may be half done when we start looking at it, so the ETA is
// measured from the progress seen since then. Failures and finished frames are printed
// as lines above the bar as they arrive.

#include <chrono>
#include <cstdio>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "tessera/v1/tessera.pb.h"

namespace tessera {

class JobProgress {
  public:
    // On a terminal the bar is redrawn every second, also while no event arrives (an
    // idle farm's job says "waiting for workers" with its time running).
    explicit JobProgress(bool quiet, std::FILE* out = stderr);
    ~JobProgress();
    // Shows the job as of `status`, printing what is new since the last call.
    void Update(const v1::JobStatus& status);
    // A line of its own (above the bar on a terminal).
    void Note(const std::string& line);
    // Ends the bar's line.
    void Finish();

  private:
    void PrintLine(const std::string& line);
    void DrawLocked();
    std::string ProgressText(const v1::JobStatus& status) const;
    // "photons 12/16" (prefixed by the frame when the job has several), or empty.
    static std::string CurrentStage(const v1::JobStatus& status);

    bool quiet_;
    std::FILE* out_;
    bool tty_;
    bool bar_drawn_ = false;
    bool first_ = true;
    std::chrono::steady_clock::time_point start_;
    int tasks_at_start_ = 0;
    int last_bucket_ = -1;  // the tenth of the job last printed as a plain line
    int last_frames_done_ = -1;
    std::string last_stage_;  // frame and stage of the last plain line
    v1::JobState last_state_ = v1::JOB_STATE_UNSPECIFIED;
    double samples_at_start_ = 0;
    std::set<std::string> failures_seen_;
    std::set<int> frames_done_;
    v1::JobStatus last_;  // what the terminal bar shows
    bool have_last_ = false;
    bool finished_ = false;
    std::mutex mu_;
    std::unique_ptr<Ticker> ticker_;  // last: stopped before the rest goes
};

}  // namespace tessera
