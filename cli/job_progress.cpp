#include "job_progress.h"

#include <unistd.h>

#include <algorithm>

#include "farm_client.h"

namespace tessera {

namespace {

std::string FailureText(const v1::TaskFailure& f) {
    return "frame " + std::to_string(f.frame()) + (f.stage().empty() ? "" : " " + f.stage()) +
           " task " + std::to_string(f.task_index()) + " attempt " + std::to_string(f.attempt()) +
           " failed on " + (f.worker().empty() ? std::string("?") : f.worker()) + ": " +
           f.message();
}

}  // namespace

JobProgress::JobProgress(bool quiet, std::FILE* out)
    : quiet_(quiet),
      out_(out),
      tty_(isatty(fileno(out)) != 0),
      start_(std::chrono::steady_clock::now()) {}

std::string JobProgress::ProgressText(const v1::JobStatus& status) const {
    int done = status.tasks_done(), total = std::max(status.tasks_total(), 1);
    double frac = std::clamp(double(done) / total, 0.0, 1.0);
    double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    int gained = done - tasks_at_start_;
    std::string eta = gained > 0 && elapsed > 0 ? FormatDuration((total - done) * elapsed / gained)
                                                : std::string("?");
    std::string text = "job " + status.job_id() + " " + JobStateName(status.state()) + " ";
    if (tty_) {
        constexpr int kWidth = 24;
        int filled = static_cast<int>(frac * kWidth);
        text += "[" + std::string(filled, '#') + std::string(kWidth - filled, '-') + "] ";
    }
    char buf[160];
    std::snprintf(buf, sizeof buf, "%d/%d tasks %d%%, frames %d/%d", done, status.tasks_total(),
                  static_cast<int>(frac * 100), FramesDone(status), status.frames_size());
    text += buf;
    if (std::string stage = CurrentStage(status); !stage.empty()) text += ", " + stage;
    if (!status.farm_problem().empty() && !IsFinished(status.state()))
        text += ", paused: " + status.farm_problem();
    return text + ", elapsed " + FormatDuration(elapsed) + ", ETA " + eta;
}

std::string JobProgress::CurrentStage(const v1::JobStatus& status) {
    const v1::FrameStatus* frame = CurrentFrame(status);
    if (!frame || IsFinished(status.state())) return "";
    std::string stage = StageProgress(*frame);
    if (stage.empty() || status.frames_size() == 1) return stage;
    return "frame " + std::to_string(frame->frame()) + " " + stage;
}

void JobProgress::PrintLine(const std::string& line) {
    // On a terminal the line replaces the bar; the next Update draws it again below.
    if (tty_ && bar_drawn_) std::fprintf(out_, "\r\033[K");
    bar_drawn_ = false;
    std::fprintf(out_, "%s\n", line.c_str());
    std::fflush(out_);
}

void JobProgress::Note(const std::string& line) {
    if (!quiet_) PrintLine(line);
}

void JobProgress::Update(const v1::JobStatus& status) {
    if (first_) tasks_at_start_ = status.tasks_done();
    // Failures come most recent first; print the new ones oldest first.
    for (int i = status.failures_size() - 1; i >= 0; --i) {
        std::string text = FailureText(status.failures(i));
        if (failures_seen_.insert(text).second) Note(text);
    }
    // Said once (the bar repeats it while it lasts): the farm is paused, not the job broken.
    if (!status.farm_problem().empty() && failures_seen_.insert(status.farm_problem()).second)
        Note(status.farm_problem());
    for (const v1::FrameStatus& f : status.frames()) {
        if (f.state() != v1::FRAME_STATE_DONE || !frames_done_.insert(f.frame()).second) continue;
        if (!first_) Note("frame " + std::to_string(f.frame()) + " done");
    }
    first_ = false;
    if (quiet_) return;
    if (tty_) {
        std::fprintf(out_, "\r\033[K%s", ProgressText(status).c_str());
        std::fflush(out_);
        bar_drawn_ = true;
        return;
    }
    int total = std::max(status.tasks_total(), 1);
    int bucket = status.tasks_done() * 10 / total;
    int frames_done = FramesDone(status);
    // The stage's name, without its count: a line when a stage starts.
    const v1::FrameStatus* frame = CurrentFrame(status);
    std::string stage = frame ? std::to_string(frame->frame()) + " " + frame->stage() : "";
    if (bucket != last_bucket_ || frames_done != last_frames_done_ ||
        status.state() != last_state_ || stage != last_stage_) {
        last_bucket_ = bucket;
        last_frames_done_ = frames_done;
        last_state_ = status.state();
        last_stage_ = stage;
        PrintLine(ProgressText(status));
    }
}

void JobProgress::Finish() {
    if (tty_ && bar_drawn_) std::fprintf(out_, "\n");
    bar_drawn_ = false;
    std::fflush(out_);
}

}  // namespace tessera
