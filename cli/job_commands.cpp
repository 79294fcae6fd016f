// `tessera status`, `watch`, `cancel`, `fetch`, `retry`, `priority`, `delete`, `logs` and
// `workers`: jobs and workers on a running coordinator.

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <optional>

#include "command_line.h"
#include "farm_commands.h"
#include "job_options.h"
#include "job_progress.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

std::string LocalTime(int64_t unix_ms) {
    if (unix_ms <= 0) return "-";
    std::time_t t = static_cast<std::time_t>(unix_ms / 1000);
    std::tm tm{};
    localtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
    return buf;
}

void PrintJobDetail(const v1::JobStatus& job) {
    int percent = job.tasks_total() > 0 ? job.tasks_done() * 100 / job.tasks_total() : 0;
    std::printf("job %s  %s\n", job.job_id().c_str(), job.name().c_str());
    std::printf("  state      %s\n", JobStateName(job.state()).c_str());
    std::printf("  priority   %d\n", job.priority());
    std::printf("  image      %dx%d, %d spp\n", job.width(), job.height(), job.spp());
    std::printf("  tasks      %d/%d done (%d%%), %lld leases granted\n", job.tasks_done(),
                job.tasks_total(), percent, static_cast<long long>(job.leases_granted()));
    std::printf("  frames     %d/%d done\n", FramesDone(job), job.frames_size());
    std::printf("  submitted  %s\n", LocalTime(job.submitted_unix_ms()).c_str());
    if (job.finished_unix_ms() > 0)
        std::printf(
            "  finished   %s (after %s)\n", LocalTime(job.finished_unix_ms()).c_str(),
            FormatDuration((job.finished_unix_ms() - job.submitted_unix_ms()) * 1e-3).c_str());
    if (!job.error().empty()) std::printf("  error      %s\n", job.error().c_str());
    if (!job.farm_problem().empty()) std::printf("  paused     %s\n", job.farm_problem().c_str());
    for (const v1::FrameStatus& f : job.frames()) {
        // The stage under way, while there is one: "photons 12/16".
        std::string stage =
            f.state() == v1::FRAME_STATE_RENDERING || f.state() == v1::FRAME_STATE_PENDING
                ? StageProgress(f)
                : "";
        std::printf("  frame %-5d %-10s %d/%d tasks%s%s%s%s\n", f.frame(),
                    FrameStateName(f.state()).c_str(), f.tasks_done(), f.tasks_total(),
                    stage.empty() ? "" : ", ", stage.c_str(), f.exr_path().empty() ? "" : "  ",
                    f.exr_path().c_str());
    }
    if (job.failures_size() > 0) std::printf("  failures (most recent first):\n");
    for (const v1::TaskFailure& f : job.failures())
        std::printf("    frame %d %s task %d attempt %d on %s: %s (tessera logs %s --task %lld)\n",
                    f.frame(), f.stage().empty() ? "render" : f.stage().c_str(), f.task_index(),
                    f.attempt(), f.worker().c_str(), f.message().c_str(), job.job_id().c_str(),
                    static_cast<long long>(f.task()));
}

void PrintJobTable(const std::vector<v1::JobStatus>& jobs) {
    if (jobs.empty()) {
        std::printf("no jobs\n");
        return;
    }
    int id_width = 6, name_width = 4;
    for (const v1::JobStatus& j : jobs) {
        id_width = std::max(id_width, static_cast<int>(j.job_id().size()));
        name_width = std::max(name_width, static_cast<int>(j.name().size()));
    }
    std::printf("%-*s  %-*s  %-9s  %4s  %-13s  %-7s  %s\n", id_width, "JOB ID", name_width, "NAME",
                "STATE", "PRIO", "TASKS", "FRAMES", "SUBMITTED");
    for (const v1::JobStatus& j : jobs) {
        std::string tasks = std::to_string(j.tasks_done()) + "/" + std::to_string(j.tasks_total());
        std::string frames = std::to_string(FramesDone(j)) + "/" + std::to_string(j.frames_size());
        std::printf("%-*s  %-*s  %-9s  %4d  %-13s  %-7s  %s\n", id_width, j.job_id().c_str(),
                    name_width, j.name().c_str(), JobStateName(j.state()).c_str(), j.priority(),
                    tasks.c_str(), frames.c_str(), LocalTime(j.submitted_unix_ms()).c_str());
    }
}

struct JobCommandOptions {
    std::string job_id;
    int priority = 0;
    std::optional<int64_t> task;
    int limit = 200;
    std::string worker;
    CoordinatorEndpoint coordinator;
    std::string output_dir;
    bool preview = false;
    bool quiet = false;
    MovieFlags movie;
};

// Workers that get no tasks for now, because they failed too many in a row.
void PrintWorkersPutAside(const std::vector<v1::WorkerStatus>& workers) {
    for (const v1::WorkerStatus& w : workers)
        if (w.state() == "put aside")
            std::printf("worker %s (%s) put aside until %s: %d tasks failed in a row\n",
                        w.name().c_str(), w.worker_id().c_str(),
                        LocalTime(w.put_aside_until_unix_ms()).c_str(), w.failures_in_a_row());
}

void RunStatus(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    if (o.job_id.empty())
        PrintJobTable(client.ListJobs());
    else
        PrintJobDetail(client.GetJob(o.job_id));
    PrintWorkersPutAside(client.ListWorkers());
}

std::string FormatBytes(uint64_t bytes) {
    char buf[32];
    if (bytes >= (uint64_t(1) << 30))
        std::snprintf(buf, sizeof buf, "%.2f GiB", bytes / double(uint64_t(1) << 30));
    else if (bytes >= (uint64_t(1) << 20))
        std::snprintf(buf, sizeof buf, "%.1f MiB", bytes / double(uint64_t(1) << 20));
    else
        std::snprintf(buf, sizeof buf, "%.1f KiB", bytes / 1024.0);
    return buf;
}

// "1.23M" for 1234567: rates in a narrow column.
std::string Rate(double per_second) {
    char buf[32];
    if (per_second >= 1e9)
        std::snprintf(buf, sizeof buf, "%.2fG", per_second * 1e-9);
    else if (per_second >= 1e6)
        std::snprintf(buf, sizeof buf, "%.2fM", per_second * 1e-6);
    else if (per_second >= 1e3)
        std::snprintf(buf, sizeof buf, "%.1fk", per_second * 1e-3);
    else
        std::snprintf(buf, sizeof buf, "%.0f", per_second);
    return buf;
}

void PrintWorkerTable(const std::vector<v1::WorkerStatus>& workers) {
    if (workers.empty()) {
        std::printf("no workers\n");
        return;
    }
    int name_width = 4;
    for (const v1::WorkerStatus& w : workers)
        name_width = std::max(name_width, static_cast<int>(w.name().size()));
    std::printf("%-*s  %-8s  %-9s  %7s  %5s  %9s  %9s  %-19s  %s\n", name_width, "NAME", "ID",
                "STATE", "THREADS", "TASKS", "SAMPLES/S", "RAYS/S", "LAST SEEN", "NOTE");
    for (const v1::WorkerStatus& w : workers) {
        std::string note;
        if (w.state() == "put aside")
            note = "until " + LocalTime(w.put_aside_until_unix_ms()) + ", " +
                   std::to_string(w.failures_in_a_row()) + " failures in a row";
        else if (w.failures_in_a_row() > 0)
            note = std::to_string(w.failures_in_a_row()) + " failures in a row";
        if (!w.current_task().empty()) note = w.current_task() + (note.empty() ? "" : "; ") + note;
        std::printf("%-*s  %-8s  %-9s  %7d  %5d  %9s  %9s  %-19s  %s\n", name_width,
                    w.name().c_str(), w.worker_id().c_str(), w.state().c_str(), w.threads(),
                    w.tasks_leased(), Rate(w.samples_per_second()).c_str(),
                    Rate(w.rays_per_second()).c_str(), LocalTime(w.last_seen_unix_ms()).c_str(),
                    note.c_str());
    }
}

void RunWorkers(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    PrintWorkerTable(client.ListWorkers());
}

void RunSetWorkerEnabled(const JobCommandOptions& o, bool enabled) {
    FarmClient client(o.coordinator);
    const v1::WorkerStatus w = client.SetWorkerEnabled(o.worker, enabled);
    spdlog::info(
        "worker {} ({}) is {}{}", w.name(), w.worker_id(), w.state(),
        w.state() == "draining" ? ": it finishes the tasks it holds, then takes no more" : "");
}

void RunRetry(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    const v1::JobStatus status = client.Retry(o.job_id);
    spdlog::info("job {} is {} again: {}/{} tasks done", o.job_id, JobStateName(status.state()),
                 status.tasks_done(), status.tasks_total());
}

void RunPriority(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    const v1::JobStatus status = client.SetPriority(o.job_id, o.priority);
    spdlog::info("job {} now has priority {}", o.job_id, status.priority());
}

void RunDelete(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    const v1::DeleteJobResponse r = client.Delete(o.job_id);
    spdlog::info(
        "job {} deleted: {} blob(s) removed ({}){}; frames already written to the output "
        "stay",
        o.job_id, r.blobs_removed(), FormatBytes(r.bytes_removed()),
        r.blobs_left_for_gc() > 0 ? ", " + std::to_string(r.blobs_left_for_gc()) +
                                        " used too recently are left to garbage collection"
                                  : std::string());
}

void RunLogs(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    const std::vector<v1::JobLogEntry> entries = client.JobLog(o.job_id, o.task, o.limit);
    if (entries.empty()) std::printf("no log entries\n");
    for (const v1::JobLogEntry& e : entries) {
        std::string where;
        if (e.task() >= 0)
            where = "task " + std::to_string(e.task()) + " (frame " + std::to_string(e.frame()) +
                    " " + e.stage() + " " + std::to_string(e.task_index()) + ")";
        else if (e.frame() >= 0)
            where =
                "frame " + std::to_string(e.frame()) + (e.stage().empty() ? "" : " ") + e.stage();
        else
            where = "job";
        std::string who;
        if (!e.worker().empty()) who = " on " + e.worker();
        if (e.attempt() > 0) who += " attempt " + std::to_string(e.attempt());
        if (e.leased_unix_ms() > 0 && e.at_unix_ms() >= e.leased_unix_ms()) {
            char took[64];
            std::snprintf(took, sizeof took, " (%.1f s after its lease)",
                          (e.at_unix_ms() - e.leased_unix_ms()) * 1e-3);
            who += took;
        }
        std::printf("%s  %-10s %s%s%s%s\n", LocalTime(e.at_unix_ms()).c_str(), e.kind().c_str(),
                    where.c_str(), who.c_str(), e.message().empty() ? "" : ": ",
                    e.message().c_str());
        if (!e.log_tail().empty()) {
            std::printf("    worker log:\n");
            size_t start = 0;
            while (start < e.log_tail().size()) {
                size_t end = e.log_tail().find('\n', start);
                if (end == std::string::npos) end = e.log_tail().size();
                std::printf("    | %s\n", e.log_tail().substr(start, end - start).c_str());
                start = end + 1;
            }
        }
    }
}

void RunWatch(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    FollowOptions follow;
    follow.quiet = o.quiet;
    follow.reconnect_seconds = 30;
    if (int code = FollowJob(client, o.job_id, follow); code != 0) throw CLI::RuntimeError(code);
}

void RunCancel(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    v1::JobStatus status = client.Cancel(o.job_id);
    spdlog::info("job {} is {}", o.job_id, JobStateName(status.state()));
}

void RunFetch(const JobCommandOptions& o) {
    FarmClient client(o.coordinator);
    for (const std::string& path : FetchFrames(client, o.job_id, o.output_dir, o.preview, o.movie))
        std::printf("%s\n", path.c_str());
}

CLI::App* AddJobCommand(CLI::App& app, const char* name, const char* help,
                        std::shared_ptr<JobCommandOptions> o, bool job_required) {
    CLI::App* cmd = app.add_subcommand(name, help);
    CLI::Option* job = cmd->add_option("job", o->job_id, "Job id");
    if (job_required) job->required();
    AddCoordinatorOption(*cmd, o->coordinator);
    return cmd;
}

}  // namespace

int FollowJob(FarmClient& client, const std::string& job_id, const FollowOptions& options) {
    v1::JobStatus job = client.Follow(job_id, options);
    double seconds = (job.finished_unix_ms() - job.submitted_unix_ms()) * 1e-3;
    switch (job.state()) {
        case v1::JOB_STATE_DONE:
            spdlog::info("job {} done: {} frame(s), {} tasks in {}", job_id, job.frames_size(),
                         job.tasks_total(), FormatDuration(std::max(seconds, 0.0)));
            return 0;
        case v1::JOB_STATE_CANCELLED:
            spdlog::error("job {} was cancelled", job_id);
            return kExitJobCancelled;
        default:
            spdlog::error("job {} failed: {}", job_id,
                          job.error().empty() ? std::string("(no reason given)") : job.error());
            return kExitJobFailed;
    }
}

std::vector<std::string> FetchFrames(FarmClient& client, const std::string& job_id,
                                     const std::string& dir, bool previews,
                                     const MovieFlags& movie) {
    v1::JobStatus job = client.GetJob(job_id);
    std::vector<int> done;
    for (const v1::FrameStatus& f : job.frames())
        if (f.state() == v1::FRAME_STATE_DONE) done.push_back(f.frame());
    if (done.empty())
        throw std::runtime_error("job " + job_id + " (" + JobStateName(job.state()) +
                                 ") has no finished frame to fetch yet");
    if (static_cast<int>(done.size()) < job.frames_size())
        spdlog::warn("job {} is {}: fetching the {} of {} frames that are done", job_id,
                     JobStateName(job.state()), done.size(), job.frames_size());
    fs::create_directories(dir);
    const bool want_movie = !movie.no_movie && done.size() >= 2;
    // Previews that only the movie needs go to a folder of their own, removed after.
    const fs::path movie_previews = fs::path(dir) / ("." + job.name() + ".movie-previews");
    if (want_movie && !previews) fs::create_directories(movie_previews);
    std::vector<std::string> written, pngs;
    for (int frame : done) {
        char number[16];
        std::snprintf(number, sizeof number, "%04d", frame);
        const std::string file = job.name() + "." + number;
        std::string stem = (fs::path(dir) / file).string();
        client.DownloadFrame(job_id, frame, false, stem + ".exr");
        written.push_back(stem + ".exr");
        if (previews) {
            client.DownloadFrame(job_id, frame, true, stem + ".png");
            written.push_back(stem + ".png");
            pngs.push_back(stem + ".png");
        } else if (want_movie) {
            pngs.push_back((movie_previews / (file + ".png")).string());
            client.DownloadFrame(job_id, frame, true, pngs.back());
        }
    }
    if (want_movie) {
        const std::string path = (fs::path(dir) / (job.name() + ".mp4")).string();
        if (MaybeWriteMoviePreview(movie, pngs, path)) written.push_back(path);
        std::error_code ec;
        if (!previews) fs::remove_all(movie_previews, ec);
    }
    return written;
}

void AddJobCommands(CLI::App& app) {
    auto status = std::make_shared<JobCommandOptions>();
    AddJobCommand(app, "status", "Show one job in detail, or all jobs as a table", status, false)
        ->callback([status] { RunStatus(*status); });

    auto workers = std::make_shared<JobCommandOptions>();
    CLI::App* workers_cmd = app.add_subcommand(
        "workers",
        "List the workers (state, current task, samples/s, rays/s, last heartbeat); "
        "`workers disable NAME` stops leasing to one, `workers enable NAME` resumes");
    AddCoordinatorOption(*workers_cmd, workers->coordinator);
    workers_cmd->require_subcommand(0, 1);
    for (const bool enable : {false, true}) {
        CLI::App* sub = workers_cmd->add_subcommand(
            enable ? "enable" : "disable",
            enable ? "Let a disabled worker take tasks again"
                   : "Lease no more tasks to a worker (it finishes those it holds); stored, "
                     "so it lasts across restarts");
        sub->add_option("worker", workers->worker, "The worker's name (or id, w-N)")->required();
        // `workers disable NAME --coordinator HOST`: the options are the parent's.
        sub->fallthrough();
        sub->callback([workers, enable] { RunSetWorkerEnabled(*workers, enable); });
    }
    workers_cmd->callback([workers, workers_cmd] {
        if (workers_cmd->get_subcommands().empty()) RunWorkers(*workers);
    });

    auto retry = std::make_shared<JobCommandOptions>();
    AddJobCommand(app, "retry",
                  "Run a failed or cancelled job again: its unwritten frames are queued, tasks "
                  "done keep their results",
                  retry, true)
        ->callback([retry] { RunRetry(*retry); });

    auto priority = std::make_shared<JobCommandOptions>();
    CLI::App* priority_cmd = AddJobCommand(
        app, "priority", "Change a job's priority (higher runs first)", priority, true);
    priority_cmd->add_option("priority", priority->priority, "The new priority")->required();
    priority_cmd->callback([priority] { RunPriority(*priority); });

    auto del = std::make_shared<JobCommandOptions>();
    AddJobCommand(app, "delete",
                  "Delete a job (cancelling it if it runs): its records and the blobs no other "
                  "job needs; frames already written stay",
                  del, true)
        ->callback([del] { RunDelete(*del); });

    auto logs = std::make_shared<JobCommandOptions>();
    CLI::App* logs_cmd = AddJobCommand(
        app, "logs",
        "Show a job's log: each task attempt (done, failed with the worker's log lines, "
        "expired), merges, frames written, priority changes, cancels, retries",
        logs, true);
    logs_cmd->add_option("--task", logs->task, "Only this task (its number in the job)")
        ->check(AtLeast(int64_t(0)));
    logs_cmd->add_option("--limit", logs->limit, "The most recent this many entries")
        ->capture_default_str()
        ->check(InRange(1, 100000));
    logs_cmd->callback([logs] { RunLogs(*logs); });

    auto watch = std::make_shared<JobCommandOptions>();
    CLI::App* watch_cmd = AddJobCommand(
        app, "watch", "Follow a job's progress; exit 0 when done, 3 failed, 4 cancelled", watch,
        true);
    watch_cmd->add_flag("-q,--quiet", watch->quiet, "No progress display, only the outcome");
    watch_cmd->callback([watch] { RunWatch(*watch); });

    auto cancel = std::make_shared<JobCommandOptions>();
    AddJobCommand(app, "cancel", "Cancel a job", cancel, true)->callback([cancel] {
        RunCancel(*cancel);
    });

    auto fetch = std::make_shared<JobCommandOptions>();
    CLI::App* fetch_cmd = AddJobCommand(
        app, "fetch", "Download a job's finished frames as DIR/<name>.<frame:04>.exr", fetch, true);
    fetch_cmd->add_option("-o,--output", fetch->output_dir, "Folder for the frames")->required();
    fetch_cmd->add_flag("--preview", fetch->preview, "Also the PNG previews (<name>.<frame>.png)");
    fetch->movie.AddTo(*fetch_cmd);
    fetch_cmd->callback([fetch] { RunFetch(*fetch); });
}

}  // namespace tessera
