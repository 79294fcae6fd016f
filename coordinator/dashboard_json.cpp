#include "dashboard_json.h"

#include <cstring>
#include <nlohmann/json.hpp>

namespace tessera {

using nlohmann::json;

std::string JobStateName(v1::JobState state) {
    return v1::JobState_Name(state).substr(std::strlen("JOB_STATE_"));
}

std::string FrameStateName(v1::FrameState state) {
    return v1::FrameState_Name(state).substr(std::strlen("FRAME_STATE_"));
}

namespace {

json FrameJson(const v1::FrameStatus& f) {
    return {{"frame", f.frame()},           {"state", FrameStateName(f.state())},
            {"tasks_done", f.tasks_done()}, {"tasks_total", f.tasks_total()},
            {"stage", f.stage()},           {"stage_label", f.stage_label()},
            {"stage_done", f.stage_done()}, {"stage_total", f.stage_total()},
            {"exr_path", f.exr_path()}};
}

json FailureJson(const v1::TaskFailure& f) {
    return {{"frame", f.frame()},     {"task_index", f.task_index()}, {"task", f.task()},
            {"stage", f.stage()},     {"worker", f.worker()},         {"attempt", f.attempt()},
            {"message", f.message()}, {"log_tail", f.log_tail()}};
}

// The frame the page shows by default: the first one rendering, else the first one not
// done, else the last one.
const v1::FrameStatus* CurrentFrame(const v1::JobStatus& job) {
    const v1::FrameStatus* not_done = nullptr;
    for (const v1::FrameStatus& f : job.frames()) {
        if (f.state() == v1::FRAME_STATE_RENDERING) return &f;
        if (!not_done && f.state() != v1::FRAME_STATE_DONE) not_done = &f;
    }
    if (not_done) return not_done;
    return job.frames().empty() ? nullptr : &job.frames(job.frames_size() - 1);
}

}  // namespace

json JobJson(const v1::JobStatus& job) {
    json frames = json::array(), failures = json::array();
    for (const v1::FrameStatus& f : job.frames()) frames.push_back(FrameJson(f));
    for (const v1::TaskFailure& f : job.failures()) failures.push_back(FailureJson(f));
    const v1::FrameStatus* current = CurrentFrame(job);
    const bool all_done = current && current->state() == v1::FRAME_STATE_DONE;
    return {
        {"job_id", job.job_id()},
        {"name", job.name()},
        {"state", JobStateName(job.state())},
        {"priority", job.priority()},
        {"tasks_done", job.tasks_done()},
        {"tasks_total", job.tasks_total()},
        {"progress", job.tasks_total() > 0 ? double(job.tasks_done()) / job.tasks_total() : 0.0},
        {"current_frame", current ? current->frame() : -1},
        {"stage_label", current && !all_done ? current->stage_label() : ""},
        {"width", job.width()},
        {"height", job.height()},
        {"spp", job.spp()},
        {"submitted_unix_ms", job.submitted_unix_ms()},
        {"finished_unix_ms", job.finished_unix_ms()},
        {"leases_granted", job.leases_granted()},
        {"error", job.error()},
        {"farm_problem", job.farm_problem()},
        {"frames", std::move(frames)},
        {"failures", std::move(failures)}};
}

json WorkerJson(const v1::WorkerStatus& w) {
    return {{"worker_id", w.worker_id()},
            {"name", w.name()},
            {"state", w.state()},
            {"threads", w.threads()},
            {"tasks_leased", w.tasks_leased()},
            {"disabled", w.disabled()},
            {"current_task", w.current_task()},
            {"samples_done", w.samples_done()},
            {"rays_traced", w.rays_traced()},
            {"samples_per_second", w.samples_per_second()},
            {"rays_per_second", w.rays_per_second()},
            {"tasks_done", w.tasks_done()},
            {"tasks_failed", w.tasks_failed()},
            {"failures_in_a_row", w.failures_in_a_row()},
            {"last_seen_unix_ms", w.last_seen_unix_ms()},
            {"put_aside_until_unix_ms", w.put_aside_until_unix_ms()}};
}

json LogEntryJson(const v1::JobLogEntry& e) {
    return {{"at_unix_ms", e.at_unix_ms()}, {"kind", e.kind()},
            {"frame", e.frame()},           {"stage", e.stage()},
            {"task_index", e.task_index()}, {"task", e.task()},
            {"worker", e.worker()},         {"attempt", e.attempt()},
            {"message", e.message()},       {"log_tail", e.log_tail()}};
}

}  // namespace tessera
