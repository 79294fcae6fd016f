#include "job_progress.h"

#include <unistd.h>

#include <algorithm>

#include "farm_client.h"

namespace tessera {

namespace {

// The camera samples a job's done tasks stand for (its frames' pixels times spp).
double SamplesDone(const v1::JobStatus& status) {
    const double total =
        double(status.width()) * status.height() * status.spp() * std::max(status.frames_size(), 1);
    return total * status.tasks_done() / std::max(status.tasks_total(), 1);
}

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
      start_(std::chrono::steady_clock::now()) {
    if (tty_ && !quiet_)
        ticker_ = std::make_unique<Ticker>(
            [this] {
                std::lock_guard lock(mu_);
                if (have_last_ && !finished_) DrawLocked();
            },
            std::chrono::seconds(1));
}

JobProgress::~JobProgress() { ticker_.reset(); }

std::string JobProgress::ProgressText(const v1::JobStatus& status) const {
    int done = status.tasks_done(), total = std::max(status.tasks_total(), 1);
    double frac = std::clamp(double(done) / total, 0.0, 1.0);
    double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    int gained = done - tasks_at_start_;
    std::string eta = gained > 0 && elapsed > 0 ? FormatDuration((total - done) * elapsed / gained)
                                                : std::string("?");
    // What matters most first: a narrow terminal cuts the end.
    std::string text;
    char buf[160];
    std::snprintf(buf, sizeof buf, "%d/%d tasks %d%%", done, status.tasks_total(),
                  static_cast<int>(frac * 100));
    text += buf;
    // No lease yet: nothing renders it.
    if (status.state() == v1::JOB_STATE_QUEUED) text += ", waiting for workers";
    if (!status.farm_problem().empty() && !IsFinished(status.state()))
        text += ", paused: " + status.farm_problem();
    if (!IsFinished(status.state())) text += ", ETA " + eta;
    text += ", frames " + std::to_string(FramesDone(status)) + "/" +
            std::to_string(status.frames_size());
    if (std::string stage = CurrentStage(status); !stage.empty()) text += ", " + stage;
    const double gained_samples = SamplesDone(status) - samples_at_start_;
    if (gained_samples > 0 && elapsed > 0.5)
        text += ", " + FormatCount(gained_samples / elapsed) + " samples/s";
    return text + ", elapsed " + FormatDuration(elapsed);
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
    std::lock_guard lock(mu_);
    if (!quiet_) PrintLine(line);
}

void JobProgress::DrawLocked() {
    const std::string head = "job " + last_.job_id() + " " + JobStateName(last_.state());
    const double frac =
        std::clamp(double(last_.tasks_done()) / std::max(last_.tasks_total(), 1), 0.0, 1.0);
    std::fprintf(out_, "\r\033[K%s",
                 FitBarLine(head, frac, ProgressText(last_), TerminalColumns(out_)).c_str());
    std::fflush(out_);
    bar_drawn_ = true;
}

void JobProgress::Update(const v1::JobStatus& status) {
    std::lock_guard lock(mu_);
    if (first_) {
        tasks_at_start_ = status.tasks_done();
        samples_at_start_ = SamplesDone(status);
    }
    // Failures come most recent first; print the new ones oldest first.
    for (int i = status.failures_size() - 1; i >= 0; --i) {
        std::string text = FailureText(status.failures(i));
        if (failures_seen_.insert(text).second && !quiet_) PrintLine(text);
    }
    // Said once (the bar repeats it while it lasts): the farm is paused, not the job broken.
    if (!status.farm_problem().empty() && failures_seen_.insert(status.farm_problem()).second &&
        !quiet_)
        PrintLine(status.farm_problem());
    for (const v1::FrameStatus& f : status.frames()) {
        if (f.state() != v1::FRAME_STATE_DONE || !frames_done_.insert(f.frame()).second) continue;
        if (!first_ && !quiet_) PrintLine("frame " + std::to_string(f.frame()) + " done");
    }
    first_ = false;
    if (quiet_) return;
    if (tty_) {
        last_ = status;
        have_last_ = true;
        DrawLocked();
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
        PrintLine("job " + status.job_id() + " " + JobStateName(status.state()) + " " +
                  ProgressText(status));
    }
}

void JobProgress::Finish() {
    ticker_.reset();
    std::lock_guard lock(mu_);
    finished_ = true;
    if (tty_ && bar_drawn_) std::fprintf(out_, "\n");
    bar_drawn_ = false;
    std::fflush(out_);
}

}  // namespace tessera
