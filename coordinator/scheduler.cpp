#include "scheduler.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/random.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>

#include "errors.h"
#include "plan/render_plan.h"

namespace tessera {

namespace {

constexpr int kMaxFailuresShown = 20;
constexpr size_t kMaxMessageBytes = 4096;

int64_t ParseId(const std::string& text, std::string_view prefix, const char* what) {
    if (text.empty()) ThrowError(ErrorCode::kInvalidArgument, std::string(what) + " is empty");
    int64_t id = 0;
    const char* begin = text.data() + prefix.size();
    const char* end = text.data() + text.size();
    bool ok = text.size() > prefix.size() && text.compare(0, prefix.size(), prefix) == 0;
    if (ok) {
        auto [ptr, ec] = std::from_chars(begin, end, id);
        ok = ec == std::errc() && ptr == end && id > 0;
    }
    if (!ok)
        ThrowError(ErrorCode::kInvalidArgument,
                   fmt::format("malformed {} '{}' (expected {}<number>)", what, text.substr(0, 80),
                               prefix));
    return id;
}

std::string FormatWorkerId(int64_t id) { return "w-" + std::to_string(id); }

std::string Truncate(std::string s) {
    if (s.size() > kMaxMessageBytes) s = s.substr(0, kMaxMessageBytes) + "...";
    return s;
}

// 128 bits from the kernel's CSPRNG, in hex.
std::string NewLeaseToken() {
    unsigned char bytes[16];
    size_t got = 0;
    while (got < sizeof bytes) {
        const ssize_t n = getrandom(bytes + got, sizeof bytes - got, 0);
        if (n < 0) {
            if (errno == EINTR) continue;
            ThrowError(ErrorCode::kInternal,
                       std::string("cannot draw a lease token: ") + std::strerror(errno));
        }
        got += static_cast<size_t>(n);
    }
    static constexpr char kHex[] = "0123456789abcdef";
    std::string token;
    for (unsigned char b : bytes) {
        token += kHex[b >> 4];
        token += kHex[b & 15];
    }
    return token;
}

// Takes as long whatever the position of the first difference.
bool ConstantTimeEquals(const std::string& a, const std::string& b) {
    if (a.size() != b.size()) return false;
    unsigned char diff = 0;
    for (size_t i = 0; i < a.size(); ++i)
        diff |= static_cast<unsigned char>(a[i]) ^ static_cast<unsigned char>(b[i]);
    return diff == 0;
}

bool IsFinished(int state) {
    return state == v1::JOB_STATE_DONE || state == v1::JOB_STATE_FAILED ||
           state == v1::JOB_STATE_CANCELLED;
}

}  // namespace

std::string FormatJobId(int64_t id) { return "job-" + std::to_string(id); }

int64_t ParseJobId(const std::string& job_id) { return ParseId(job_id, "job-", "job id"); }

Scheduler::Scheduler(const std::string& db_path, const SchedulerOptions& options,
                     const Clock& clock)
    : clock_(clock), options_(options), store_(db_path) {
    const int64_t now = clock_.NowMs();
    last_lease_id_ = store_.GetMeta("last_lease_id", 0);
    for (const WorkerRow& w : store_.Workers()) {
        Worker& worker = workers_[w.id];
        worker.name = w.name;
        worker.threads = w.threads;
        worker.last_seen_ms = now;
        worker.disabled = w.disabled;
    }
    // A lease from before tokens were stored has an empty one: only its worker, which
    // sends none, may finish it.
    for (const TaskRow& t : store_.LeasedTasks()) {
        leases_[t.id] = {
            t.lease_id,
            t.worker_id,
            t.job_id,
            now + options_.lease_ms,
            t.lease_token,
            t.stage,
            fmt::format("{} frame {} {} {}", FormatJobId(t.job_id), t.frame, t.stage, t.task_index),
            now};
        last_lease_id_ = std::max(last_lease_id_, t.lease_id);
    }
    if (!leases_.empty())
        spdlog::info(
            "recovered {} outstanding leases; each expires {} ms from now unless its "
            "worker heartbeats",
            leases_.size(), options_.lease_ms);
}

void Scheduler::Emit(const Events& events) {
    if (!listener_) return;
    for (const Event& e : events) {
        switch (e.kind) {
            case Event::kWork:
                listener_->OnWorkAvailable();
                break;
            case Event::kJob:
                listener_->OnJobChanged(e.job_id, e.message);
                break;
            case Event::kStageReady:
                listener_->OnStageReady(e.job_id, e.frame, e.stage);
                break;
            case Event::kFrameReady:
                listener_->OnFrameReady(e.job_id, e.frame);
                break;
        }
    }
}

Scheduler::Worker& Scheduler::FindWorker(const std::string& worker_id, int64_t* id) {
    *id = ParseId(worker_id, "w-", "worker id");
    auto it = workers_.find(*id);
    if (it == workers_.end())
        ThrowError(ErrorCode::kNotFound, "unknown worker " + worker_id + ": register again");
    Worker& w = it->second;
    w.last_seen_ms = clock_.NowMs();
    if (w.silent) {
        w.silent = false;
        spdlog::info("worker '{}' ({}) is back", w.name, worker_id);
    }
    return w;
}

std::string Scheduler::WorkerName(int64_t worker_id) const {
    auto it = workers_.find(worker_id);
    return it == workers_.end() ? FormatWorkerId(worker_id) : it->second.name;
}

JobRow Scheduler::LoadJob(int64_t job_id) {
    std::optional<JobRow> job = store_.GetJob(job_id);
    if (!job) ThrowError(ErrorCode::kNotFound, "no job " + FormatJobId(job_id));
    return std::move(*job);
}

std::shared_ptr<const Scheduler::JobInfo> Scheduler::Info(int64_t job_id) {
    auto it = jobs_.find(job_id);
    if (it != jobs_.end()) return it->second;
    JobRow row = LoadJob(job_id);
    auto info = std::make_shared<JobInfo>();
    auto spec = std::make_shared<v1::JobSpec>();
    if (!spec->ParseFromString(store_.GetJobSpec(job_id)))
        ThrowError(ErrorCode::kInternal, "stored spec of " + FormatJobId(job_id) + " is corrupt");
    info->spec = std::move(spec);
    info->name = row.name;
    try {
        info->settings = DecodeRenderSettings(row.render_settings);
        info->plan = std::make_shared<const RenderPlan>(
            MakeRenderPlan(info->settings.resolution, info->settings));
    } catch (const std::exception& e) {
        ThrowError(ErrorCode::kInternal, fmt::format("stored settings of {} cannot be planned: {}",
                                                     FormatJobId(job_id), e.what()));
    }
    info->first_task_id = row.first_task_id;
    info->tasks_total = row.tasks_total;
    jobs_.emplace(job_id, info);
    return info;
}

WorkerRegistration Scheduler::RegisterWorker(const std::string& name, int threads) {
    if (name.size() > 256)
        ThrowError(ErrorCode::kInvalidArgument, "worker name is longer than 256 bytes");
    for (char c : name)
        if (static_cast<unsigned char>(c) < 0x20)
            ThrowError(ErrorCode::kInvalidArgument, "worker name contains a control character");
    std::lock_guard lock(mu_);
    const int64_t now = clock_.NowMs();
    std::string shown = name.empty() ? "worker" : name;
    // A worker that registers under a known name is that worker restarted: it takes the
    // old id (and keeps any time it was put aside for) rather than growing the workers
    // table by a row per restart. This holds even when the old run was seen moments ago:
    // a worker restarted quickly (a crash, a redeploy, a supervisor's restart) registers
    // before its old run's leases run out, and is no second worker. The old run's leases
    // are left to expire and are then handed to others. Names are unique per worker (the
    // default, host-pid, is); two live processes given one name share the id, which stays
    // safe because every lease is fenced by its own token.
    int64_t id = 0;
    for (const auto& [known_id, w] : workers_)
        if (w.name == shown && (id == 0 || known_id < id)) id = known_id;  // the oldest
    if (id != 0 && now - workers_[id].last_seen_ms < options_.lease_ms)
        spdlog::info(
            "worker '{}' registered while its previous run as {} was seen {} ms ago: taken as "
            "a restart of it (that run's leases expire within {} ms)",
            shown, FormatWorkerId(id), now - workers_[id].last_seen_ms, options_.lease_ms);
    if (id != 0) {
        store_.UpdateWorker(id, threads, now);
        Worker& w = workers_[id];
        w.threads = threads;
        w.last_seen_ms = now;
        w.silent = false;
        w.failures_in_a_row = 0;
        spdlog::info("worker '{}' registered again as {} ({} threads)", shown, FormatWorkerId(id),
                     threads);
    } else {
        id = store_.InsertWorker(shown, threads, now);
        Worker& w = workers_[id];
        w.name = shown;
        w.threads = threads;
        w.last_seen_ms = now;
        spdlog::info("worker '{}' registered as {} ({} threads)", shown, FormatWorkerId(id),
                     threads);
    }
    WorkerRegistration r;
    r.worker_id = FormatWorkerId(id);
    r.lease_duration_ms = static_cast<int>(options_.lease_ms);
    r.heartbeat_interval_ms = static_cast<int>(std::max<int64_t>(1, options_.lease_ms / 3));
    return r;
}

std::optional<LeasedTask> Scheduler::TryLease(const std::string& worker_id) {
    Events events;
    std::optional<LeasedTask> out;
    {
        std::lock_guard lock(mu_);
        int64_t wid = 0;
        Worker& worker = FindWorker(worker_id, &wid);
        const int64_t now = clock_.NowMs();
        if (worker.put_aside_until_ms > now || worker.disabled) return std::nullopt;
        if (worker.put_aside_until_ms != 0) {
            worker.put_aside_until_ms = 0;
            spdlog::info("worker '{}' ({}) is back from being put aside", worker.name, worker_id);
        }
        std::optional<TaskRow> task = NextTaskFor(wid, now);
        if (!task) return std::nullopt;
        const std::shared_ptr<const JobInfo> info = Info(task->job_id);
        const std::string job_id = FormatJobId(task->job_id);
        const std::vector<TaskInputRef> inputs = Inputs(*info, *task);
        SqliteTransaction txn(store_.Db());
        const int job_state = store_.JobState(task->job_id).value_or(0);
        const int64_t lease_id = last_lease_id_ + 1;
        std::string token = NewLeaseToken();
        store_.SetMeta("last_lease_id", lease_id);
        store_.LeaseTask(task->id, lease_id, wid, token);
        store_.CountLease(task->job_id, now);
        store_.MarkFrameRendering(task->job_id, task->frame, now);
        const bool frame_started = store_.Db().Changes() == 1;
        txn.Commit();
        last_lease_id_ = lease_id;
        ++counters_.leases_granted;
        const int stage_tasks = task->stage_index < static_cast<int>(info->plan->stages.size())
                                    ? info->plan->stages[task->stage_index].num_tasks
                                    : 0;
        leases_[task->id] = {lease_id,
                             wid,
                             task->job_id,
                             now + options_.lease_ms,
                             token,
                             task->stage,
                             fmt::format("{} frame {} {} {}/{}", job_id, task->frame, task->stage,
                                         task->task_index + 1, stage_tasks),
                             now};

        out.emplace();
        out->task_id = task->id;
        out->lease_id = lease_id;
        out->lease_token = std::move(token);
        out->job_id = job_id;
        out->frame = task->frame;
        out->stage = task->stage;
        out->task_index = task->task_index;
        out->attempt = task->attempts + 1;
        out->spec = info->spec;
        out->deadline_ms = now + options_.lease_ms;
        out->inputs = inputs;
        spdlog::debug("lease {}: task {} ({} frame {} {} {}, attempt {}) to worker '{}'", lease_id,
                      task->id, job_id, task->frame, task->stage, task->task_index, out->attempt,
                      worker.name);
        if (job_state == v1::JOB_STATE_QUEUED) {
            spdlog::info("job {} '{}' is running", job_id, info->name);
            events.push_back({Event::kJob, job_id, "job running"});
        }
        if (frame_started)
            events.push_back({Event::kJob, job_id, fmt::format("frame {} rendering", task->frame)});
    }
    Emit(events);
    return out;
}

std::optional<TaskRow> Scheduler::NextTaskFor(int64_t wid, int64_t now) {
    std::optional<TaskRow> task = store_.NextPendingTask();
    // Another live worker is likelier to succeed; a lone worker retries (the job must
    // still finish or fail).
    if (task && task->failed_worker_id == wid && OtherWorkerLive(wid, now))
        task = store_.NextPendingTaskAvoiding(wid);
    return task;
}

bool Scheduler::OtherWorkerLive(int64_t wid, int64_t now) const {
    for (const auto& [id, w] : workers_)
        if (id != wid && !w.silent && now - w.last_seen_ms <= options_.lease_ms &&
            w.put_aside_until_ms <= now)
            return true;
    return false;
}

void Scheduler::CountWorkerFailure(int64_t wid, Worker& worker, int64_t now) {
    if (options_.max_failures_in_a_row <= 0) return;
    if (++worker.failures_in_a_row < options_.max_failures_in_a_row) return;
    worker.failures_in_a_row = 0;
    worker.put_aside_until_ms = now + options_.put_aside_ms;
    ++times_put_aside_;
    spdlog::warn("worker '{}' ({}) failed {} tasks in a row: put aside, no leases for {} s",
                 worker.name, FormatWorkerId(wid), options_.max_failures_in_a_row,
                 options_.put_aside_ms / 1000);
}

std::vector<std::string> Scheduler::WorkersPutAside() {
    std::lock_guard lock(mu_);
    const int64_t now = clock_.NowMs();
    std::vector<std::string> names;
    for (const auto& [id, w] : workers_)
        if (w.put_aside_until_ms > now) names.push_back(w.name);
    std::sort(names.begin(), names.end());
    return names;
}

int64_t Scheduler::TimesWorkersPutAside() {
    std::lock_guard lock(mu_);
    return times_put_aside_;
}

int64_t Scheduler::UnfinishedTasks() {
    std::lock_guard lock(mu_);
    return store_.UnfinishedTasks();
}

std::vector<v1::WorkerStatus> Scheduler::ListWorkers() {
    std::lock_guard lock(mu_);
    const int64_t now = clock_.NowMs();
    std::vector<v1::WorkerStatus> list;
    for (const auto& [id, w] : workers_) list.push_back(WorkerStatusOf(id, w, now));
    std::sort(list.begin(), list.end(), [](const v1::WorkerStatus& a, const v1::WorkerStatus& b) {
        return std::tie(a.name(), a.worker_id()) < std::tie(b.name(), b.worker_id());
    });
    return list;
}

v1::WorkerStatus Scheduler::WorkerStatusOf(int64_t id, const Worker& w, int64_t now) {
    int leased = 0;
    const Lease* current = nullptr;
    for (const auto& [task_id, lease] : leases_)
        if (lease.worker_id == id) {
            ++leased;
            if (!current || lease.lease_id < current->lease_id) current = &lease;
        }
    v1::WorkerStatus s;
    s.set_worker_id(FormatWorkerId(id));
    s.set_name(w.name);
    s.set_threads(w.threads);
    s.set_tasks_leased(leased);
    s.set_last_seen_unix_ms(w.last_seen_ms);
    s.set_failures_in_a_row(w.failures_in_a_row);
    s.set_disabled(w.disabled);
    if (current) s.set_current_task(current->what);
    s.set_samples_done(static_cast<int64_t>(w.report.samples_done));
    s.set_rays_traced(static_cast<int64_t>(w.report.rays_traced));
    // Rates go stale with the reports that made them.
    const bool fresh = w.report_ms > 0 && now - w.report_ms <= options_.lease_ms;
    s.set_samples_per_second(fresh ? w.samples_per_second : 0.0);
    s.set_rays_per_second(fresh ? w.rays_per_second : 0.0);
    s.set_tasks_done(w.tasks_done);
    s.set_tasks_failed(w.tasks_failed);
    if (w.silent) {
        s.set_state("silent");
    } else if (w.disabled) {
        s.set_state(leased > 0 ? "draining" : "disabled");
    } else if (w.put_aside_until_ms > now) {
        s.set_state("put aside");
        s.set_put_aside_until_unix_ms(w.put_aside_until_ms);
    } else {
        s.set_state(leased > 0 ? "busy" : "idle");
    }
    return s;
}

HeartbeatReply Scheduler::Heartbeat(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                                    const std::string& lease_token, const WorkerReport& report) {
    std::lock_guard lock(mu_);
    int64_t wid = 0;
    Worker& worker = FindWorker(worker_id, &wid);
    if (report.samples_done != 0 || report.rays_traced != 0) {
        const int64_t now = clock_.NowMs();
        const int64_t dt = now - worker.report_ms;
        // Totals restart with the worker process: a smaller total starts a new series.
        const bool restarted = report.samples_done < worker.report.samples_done ||
                               report.rays_traced < worker.report.rays_traced;
        if (worker.report_ms > 0 && !restarted && dt >= 200) {
            worker.samples_per_second =
                double(report.samples_done - worker.report.samples_done) * 1000.0 / double(dt);
            worker.rays_per_second =
                double(report.rays_traced - worker.report.rays_traced) * 1000.0 / double(dt);
        }
        if (worker.report_ms == 0 || restarted || dt >= 200) {
            worker.report = report;
            worker.report_ms = now;
        }
    }
    HeartbeatReply reply;
    if (task_id == 0) return reply;
    auto it = leases_.find(task_id);
    if (it != leases_.end() && it->second.lease_id == lease_id) {
        CheckHolder(it->second, wid, lease_token, task_id);
        it->second.deadline_ms = clock_.NowMs() + options_.lease_ms;
        reply.lease_valid = true;
        return reply;
    }
    if (std::optional<TaskRow> task = store_.GetTask(task_id))
        reply.cancelled = store_.JobState(task->job_id) == v1::JOB_STATE_CANCELLED;
    return reply;
}

void Scheduler::CheckHolder(const Lease& lease, int64_t wid, const std::string& token,
                            int64_t task_id) const {
    // Evaluated in full either way, so that the time taken tells nothing.
    const bool token_ok = ConstantTimeEquals(lease.token, token);
    if (lease.worker_id == wid && token_ok) return;
    throw LeaseNotHeld(fmt::format(
        "task {}: worker {} does not hold this lease (another worker's lease, or a wrong "
        "lease token); refused",
        task_id, FormatWorkerId(wid)));
}

const Scheduler::Lease& Scheduler::CurrentLease(int64_t wid, int64_t task_id, int64_t lease_id,
                                                const std::string& token, TaskRow* task) {
    std::optional<TaskRow> row = store_.GetTask(task_id);
    if (!row) ThrowError(ErrorCode::kNotFound, fmt::format("unknown task {}", task_id));
    auto it = leases_.find(task_id);
    if (it != leases_.end() && it->second.lease_id == lease_id) {
        CheckHolder(it->second, wid, token, task_id);
        *task = std::move(*row);
        return it->second;
    }
    std::string why;
    const int job_state = store_.JobState(row->job_id).value_or(0);
    if (job_state == v1::JOB_STATE_CANCELLED)
        why = "its job was cancelled";
    else if (job_state == v1::JOB_STATE_FAILED)
        why = "its job failed";
    else if (row->state == TaskState::kDone)
        why = "the task is already done";
    else if (row->state == TaskState::kLeased)
        why = "the task is now under another lease";
    else
        why = "the lease expired and the task was re-queued";
    ThrowError(ErrorCode::kFailedPrecondition,
               fmt::format("stale lease {} for task {}: {}; the result is discarded", lease_id,
                           task_id, why));
}

std::vector<TaskInputRef> Scheduler::Inputs(const JobInfo& info, const TaskRow& task) {
    const std::vector<StagePlan>& stages = info.plan->stages;
    if (task.stage_index < 0 || task.stage_index >= static_cast<int>(stages.size()))
        ThrowError(ErrorCode::kInternal, fmt::format("task {} has stage {}, its plan {} stages",
                                                     task.id, task.stage_index, stages.size()));
    const std::vector<int>& reads = stages[task.stage_index].reads;
    std::vector<TaskInputRef> inputs;
    if (reads.empty()) return inputs;
    const std::vector<StageRow> rows = store_.GetFrameStages(task.job_id, task.frame);
    for (int r : reads) {
        // Its tasks were released by the merge of what they read: never without it.
        if (r >= static_cast<int>(rows.size()) || !rows[r].merged)
            ThrowError(ErrorCode::kInternal,
                       fmt::format("task {} ({} of frame {}) is pending, but stage {} it reads "
                                   "is not merged",
                                   task.id, task.stage, task.frame, stages[r].name));
        inputs.push_back({rows[r].name, rows[r].artifact_hash, rows[r].artifact_size});
    }
    return inputs;
}

LeaseCheck Scheduler::CheckLease(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                                 const std::string& lease_token) {
    std::lock_guard lock(mu_);
    int64_t wid = 0;
    FindWorker(worker_id, &wid);
    TaskRow task;
    const Lease& lease = CurrentLease(wid, task_id, lease_id, lease_token, &task);
    const std::shared_ptr<const JobInfo> info = Info(lease.job_id);
    if (task.stage_index < 0 || task.stage_index >= static_cast<int>(info->plan->stages.size()))
        ThrowError(ErrorCode::kInternal, fmt::format("task {} has no stage", task_id));
    return {FormatJobId(task.job_id), task.frame, task.stage_index, task.task_index, info->plan};
}

void Scheduler::Complete(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                         const std::string& lease_token, const std::string& result_hash) {
    Events events;
    {
        std::lock_guard lock(mu_);
        int64_t wid = 0;
        Worker& worker = FindWorker(worker_id, &wid);
        TaskRow task;
        const int64_t leased_ms =
            CurrentLease(wid, task_id, lease_id, lease_token, &task).leased_ms;
        const std::string job_id = FormatJobId(task.job_id);
        const std::shared_ptr<const JobInfo> info = Info(task.job_id);
        if (task.stage_index < 0 || task.stage_index >= static_cast<int>(info->plan->stages.size()))
            ThrowError(ErrorCode::kInternal, fmt::format("task {} has no stage", task_id));
        const StagePlan& stage = info->plan->stages[task.stage_index];
        SqliteTransaction txn(store_.Db());
        if (!store_.CompleteTask(task_id, lease_id, result_hash))
            ThrowError(ErrorCode::kInternal,
                       fmt::format("task {} changed under its lease", task_id));
        store_.CountTaskDone(task.job_id);
        store_.CountFrameTaskDone(task.job_id, task.frame);
        const int stage_done = store_.CountStageTaskDone(task.job_id, task.frame, task.stage_index);
        Log(task.job_id, "done", &task, info->first_task_id, worker.name, task.attempts,
            fmt::format("result {}", result_hash.substr(0, 12)), {}, leased_ms);
        txn.Commit();
        leases_.erase(task_id);
        worker.failures_in_a_row = 0;
        ++worker.tasks_done;
        ++counters_.completed_by_stage[stage.name];
        spdlog::debug("lease {}: task {} ({} frame {} {} {}) completed by worker '{}' ({}/{})",
                      lease_id, task_id, job_id, task.frame, stage.name, task.task_index,
                      worker.name, stage_done, stage.num_tasks);
        events.push_back(
            {Event::kJob, job_id,
             fmt::format("{} task {} of frame {} done", stage.name, task.task_index, task.frame)});
        if (stage_done == stage.num_tasks) {
            if (stage.produces_artifact) {
                spdlog::info("job {} frame {}: all {} tasks of {} done; merging", job_id,
                             task.frame, stage.num_tasks, stage.name);
                events.push_back({Event::kStageReady, job_id, "", task.frame, task.stage_index});
            } else if (FrameStagesDone(task.job_id, task.frame, *info->plan)) {
                spdlog::info("job {} frame {}: all {} tasks done; assembling", job_id, task.frame,
                             info->plan->TotalTasks());
                events.push_back({Event::kFrameReady, job_id, "", task.frame});
            }
        }
    }
    Emit(events);
}

void Scheduler::Fail(const std::string& worker_id, int64_t task_id, int64_t lease_id,
                     const std::string& lease_token, const std::string& message,
                     const std::string& log_tail) {
    Events events;
    {
        std::lock_guard lock(mu_);
        int64_t wid = 0;
        Worker& worker = FindWorker(worker_id, &wid);
        TaskRow task;
        const int64_t leased_ms =
            CurrentLease(wid, task_id, lease_id, lease_token, &task).leased_ms;
        const std::string job_id = FormatJobId(task.job_id);
        const std::string text = Truncate(message.empty() ? "(no message)" : message);
        const int failures = task.failures + 1;
        const std::string tail =
            log_tail.size() > 8192 ? log_tail.substr(log_tail.size() - 8192) : log_tail;
        const int64_t first_task_id = Info(task.job_id)->first_task_id;
        SqliteTransaction txn(store_.Db());
        store_.RequeueTask(task_id, lease_id, true);
        store_.InsertFailure(task.job_id,
                             {task.frame, task.task_index, task.attempts, worker.name, text,
                              task.stage, tail, task.id - first_task_id},
                             clock_.NowMs());
        Log(task.job_id, "failed", &task, first_task_id, worker.name, task.attempts, text, tail,
            leased_ms);
        ++worker.tasks_failed;
        ++counters_.failed_by_stage[task.stage];
        spdlog::warn(
            "lease {}: task {} ({} frame {} {} {}) failed on worker '{}' (failure {} of "
            "{}): {}",
            lease_id, task_id, job_id, task.frame, task.stage, task.task_index, worker.name,
            failures, options_.max_attempts, text);
        events.push_back({Event::kJob, job_id,
                          fmt::format("{} task {} of frame {} failed on {}: {}", task.stage,
                                      task.task_index, task.frame, worker.name, text)});
        if (failures >= options_.max_attempts) {
            std::string error =
                fmt::format("{} task {} of frame {} failed {} times; last error on worker {}: {}",
                            task.stage, task.task_index, task.frame, failures, worker.name, text);
            EndJob(task.job_id, v1::JOB_STATE_FAILED, error);
            events.push_back({Event::kJob, job_id, "job failed: " + error});
        } else {
            events.push_back({Event::kWork, job_id, ""});
        }
        txn.Commit();
        // Only once committed: a lease dropped from memory alone would never expire.
        leases_.erase(task_id);
        CountWorkerFailure(wid, worker, clock_.NowMs());
    }
    Emit(events);
}

void Scheduler::Release(int64_t task_id, int64_t lease_id) {
    {
        std::lock_guard lock(mu_);
        auto it = leases_.find(task_id);
        if (it == leases_.end() || it->second.lease_id != lease_id) return;
        SqliteTransaction txn(store_.Db());
        store_.ReleaseTask(task_id, lease_id, it->second.job_id);
        txn.Commit();
        spdlog::debug("lease {}: task {} given back unused (the worker left)", lease_id, task_id);
        leases_.erase(it);
    }
    Emit({{Event::kWork, "", ""}});
}

int Scheduler::Sweep() {
    Events events;
    int expired = 0;
    {
        std::lock_guard lock(mu_);
        const int64_t now = clock_.NowMs();
        std::vector<int64_t> due;
        for (const auto& [task_id, lease] : leases_)
            if (lease.deadline_ms <= now) due.push_back(task_id);
        if (!due.empty()) {
            std::sort(due.begin(), due.end());
            SqliteTransaction txn(store_.Db());
            for (int64_t task_id : due) {
                const Lease lease = leases_[task_id];
                store_.RequeueTask(task_id, lease.lease_id, false);
                const std::string job_id = FormatJobId(lease.job_id);
                if (std::optional<TaskRow> task = store_.GetTask(task_id)) {
                    const std::optional<JobRow> job = store_.GetJob(lease.job_id);
                    Log(lease.job_id, "expired", &*task, job ? job->first_task_id : 0,
                        WorkerName(lease.worker_id), task->attempts,
                        fmt::format("lease {} expired; re-queued", lease.lease_id), {},
                        lease.leased_ms);
                }
                ++counters_.leases_expired;
                ++counters_.expired_by_stage[lease.stage];
                spdlog::warn("lease {}: task {} ({}) on worker '{}' expired; re-queued",
                             lease.lease_id, task_id, job_id, WorkerName(lease.worker_id));
                events.push_back({Event::kJob, job_id,
                                  fmt::format("lease of task {} on {} expired; re-queued", task_id,
                                              WorkerName(lease.worker_id))});
            }
            txn.Commit();
            // Only once committed: a lease dropped from memory alone would never expire.
            for (int64_t task_id : due) leases_.erase(task_id);
            expired = static_cast<int>(due.size());
            events.push_back({Event::kWork, "", ""});
        }
        // Idle workers wait in long polls of up to 30 s between calls.
        const int64_t silence_ms = 3 * options_.lease_ms + 30000;
        for (auto& [id, w] : workers_) {
            if (!w.silent && now - w.last_seen_ms > silence_ms) {
                w.silent = true;
                spdlog::info("worker '{}' ({}) silent for {} s; presumed gone", w.name,
                             FormatWorkerId(id), (now - w.last_seen_ms) / 1000);
            }
        }
    }
    Emit(events);
    return expired;
}

void Scheduler::EndJob(int64_t job_id, int state, const std::string& error) {
    const JobRow job = LoadJob(job_id);
    store_.SetJobState(job_id, state, error, clock_.NowMs());
    store_.DropTasks(job.first_task_id, job.first_task_id + job.tasks_total - 1);
    // No frame of an ended job stays PENDING or RENDERING.
    store_.EndOpenFrames(
        job_id, state == v1::JOB_STATE_FAILED ? v1::FRAME_STATE_FAILED : v1::FRAME_STATE_CANCELLED);
    for (auto it = leases_.begin(); it != leases_.end();) {
        if (it->second.job_id == job_id) {
            spdlog::debug("lease {}: task {} revoked ({} ended)", it->second.lease_id, it->first,
                          FormatJobId(job_id));
            it = leases_.erase(it);
        } else {
            ++it;
        }
    }
    Log(job_id, state == v1::JOB_STATE_FAILED ? "job-failed" : "cancelled", nullptr, 0, "", 0,
        error);
    spdlog::log(state == v1::JOB_STATE_FAILED ? spdlog::level::err : spdlog::level::info,
                "job {} '{}' {}{}", FormatJobId(job_id), job.name,
                state == v1::JOB_STATE_FAILED ? "failed: " : "cancelled", error);
    jobs_.erase(job_id);
}

std::string Scheduler::AddJob(NewJob job) {
    RenderPlan plan;
    try {
        const RenderSettings settings = DecodeRenderSettings(job.render_settings);
        plan = MakeRenderPlan(settings.resolution, settings);
    } catch (const std::invalid_argument& e) {
        ThrowError(ErrorCode::kInvalidArgument,
                   std::string("the job cannot be planned: ") + e.what());
    }
    job.stages.clear();
    for (const StagePlan& s : plan.stages)
        job.stages.push_back({s.name, s.label.empty() ? s.name : s.label, s.num_tasks,
                              s.produces_artifact, !s.reads.empty()});
    std::string job_id;
    {
        std::lock_guard lock(mu_);
        SqliteTransaction txn(store_.Db());
        const int64_t id = store_.InsertJob(job, clock_.NowMs());
        Log(id, "submitted", nullptr, 0, "", 0,
            fmt::format("{} tasks per frame, priority {}", job.TasksPerFrame(), job.priority));
        txn.Commit();
        job_id = FormatJobId(id);
        const int frames = job.NumFrames();
        const std::string frame_text =
            job.frames.empty()
                ? fmt::format("{}..{}", job.frame_start, job.frame_end)
                : fmt::format("{} listed in {}..{}", frames, job.frame_start, job.frame_end);
        std::string stages;
        for (const NewStage& s : job.stages)
            stages += fmt::format("{}{} {}", stages.empty() ? "" : ", ", s.name, s.num_tasks);
        spdlog::info(
            "job {} '{}' submitted: frames {}, {}x{}, {} spp, {} {} tasks ({} per frame: "
            "{}), priority {}",
            job_id, job.name, frame_text, job.settings.width, job.settings.height, job.settings.spp,
            job.settings.integrator, int64_t(frames) * job.TasksPerFrame(), job.TasksPerFrame(),
            stages, job.priority);
    }
    Emit({{Event::kJob, job_id, "job queued"}, {Event::kWork, job_id, ""}});
    return job_id;
}

v1::JobStatus Scheduler::BuildStatus(int64_t job_id) {
    JobRow job = LoadJob(job_id);
    v1::JobStatus s;
    s.set_job_id(FormatJobId(job.id));
    s.set_name(job.name);
    s.set_state(static_cast<v1::JobState>(job.state));
    s.set_priority(job.priority);
    s.set_tasks_done(job.tasks_done);
    s.set_tasks_total(job.tasks_total);
    const std::vector<StageRow> stages = store_.GetStages(job_id);
    size_t next_stage = 0;
    for (const FrameRow& f : store_.GetFrames(job_id)) {
        v1::FrameStatus* fs = s.add_frames();
        fs->set_frame(f.frame);
        fs->set_state(static_cast<v1::FrameState>(f.state));
        fs->set_tasks_done(f.tasks_done);
        fs->set_tasks_total(f.tasks_total);
        fs->set_exr_path(f.exr_path);
        // The stage under way: the first not finished, else the last.
        const StageRow* current = nullptr;
        for (; next_stage < stages.size() && stages[next_stage].frame == f.frame; ++next_stage)
            if (!current || current->Finished()) current = &stages[next_stage];
        if (current) {
            fs->set_stage(current->name);
            fs->set_stage_label(current->label);
            fs->set_stage_done(current->tasks_done);
            fs->set_stage_total(current->num_tasks);
        }
    }
    s.set_error(job.error);
    for (const FailureRow& f : store_.RecentFailures(job_id, kMaxFailuresShown)) {
        v1::TaskFailure* tf = s.add_failures();
        tf->set_frame(f.frame);
        tf->set_task_index(f.task_index);
        tf->set_worker(f.worker);
        tf->set_message(f.message);
        tf->set_attempt(f.attempt);
        tf->set_stage(f.stage);
        tf->set_log_tail(f.log_tail);
        tf->set_task(f.task);
    }
    s.set_submitted_unix_ms(job.submitted_ms);
    s.set_finished_unix_ms(job.finished_ms);
    s.set_width(job.settings.width);
    s.set_height(job.settings.height);
    s.set_spp(job.settings.spp);
    s.set_leases_granted(job.leases_granted);
    if (!IsFinished(job.state)) s.set_farm_problem(farm_problem_);
    return s;
}

void Scheduler::SetFarmProblem(const std::string& problem) {
    std::lock_guard lock(mu_);
    farm_problem_ = problem;
}

v1::JobStatus Scheduler::GetJob(const std::string& job_id) {
    const int64_t id = ParseJobId(job_id);
    std::lock_guard lock(mu_);
    return BuildStatus(id);
}

std::vector<v1::JobStatus> Scheduler::ListJobs() {
    std::lock_guard lock(mu_);
    std::vector<v1::JobStatus> out;
    for (int64_t id : store_.JobIds()) out.push_back(BuildStatus(id));
    return out;
}

std::map<v1::JobState, int64_t> Scheduler::JobCountsByState() {
    std::lock_guard lock(mu_);
    std::map<v1::JobState, int64_t> counts;
    for (const auto& [state, n] : store_.JobCountsByState())
        if (v1::JobState_IsValid(state)) counts[static_cast<v1::JobState>(state)] = n;
    return counts;
}

v1::JobStatus Scheduler::Cancel(const std::string& job_id) {
    const int64_t id = ParseJobId(job_id);
    v1::JobStatus status;
    {
        std::lock_guard lock(mu_);
        JobRow job = LoadJob(id);
        if (IsFinished(job.state)) return BuildStatus(id);
        SqliteTransaction txn(store_.Db());
        EndJob(id, v1::JOB_STATE_CANCELLED, "");
        txn.Commit();
        status = BuildStatus(id);
    }
    Emit({{Event::kJob, job_id, "job cancelled"}});
    return status;
}

bool Scheduler::FrameStagesDone(int64_t job_id, int frame, const RenderPlan& plan) {
    for (int stage : plan.FrameStages()) {
        const std::optional<StageRow> row = store_.GetStage(job_id, frame, stage);
        if (!row || row->tasks_done != row->num_tasks) return false;
    }
    return true;
}

FrameAssemblyInput Scheduler::GetAssemblyInput(const std::string& job_id, int frame) {
    const int64_t id = ParseJobId(job_id);
    std::lock_guard lock(mu_);
    JobRow job = LoadJob(id);
    std::optional<FrameRow> row = store_.GetFrame(id, frame);
    if (!row) ThrowError(ErrorCode::kNotFound, fmt::format("{} has no frame {}", job_id, frame));
    FrameAssemblyInput in;
    in.job_id = job_id;
    in.name = job.name;
    in.frame = frame;
    in.job_running = job.state == v1::JOB_STATE_RUNNING;
    if (!in.job_running) return in;
    const std::shared_ptr<const JobInfo> info = Info(id);
    in.settings = info->settings;
    in.settings.frame = frame;
    in.scene_name = job.settings.scene_name;
    in.started_ms = row->started_ms;
    std::optional<StageRow> render = store_.GetStage(id, frame, info->plan->RenderStageIndex());
    if (!render)
        ThrowError(ErrorCode::kInternal,
                   fmt::format("{} frame {} has no render stage", job_id, frame));
    in.render_stage = render->index;
    in.results = store_.StageResults(*render, &in.completions);
    for (int stage : info->plan->FrameStages()) {
        if (stage == render->index) continue;
        std::optional<StageRow> row = store_.GetStage(id, frame, stage);
        if (!row)
            ThrowError(ErrorCode::kInternal,
                       fmt::format("{} frame {} has no stage {}", job_id, frame, stage));
        FrameAssemblyInput::Contribution c;
        c.stage = stage;
        c.results = store_.StageResults(*row, &c.completions);
        in.contributions.push_back(std::move(c));
    }
    return in;
}

StageMergeInput Scheduler::GetMergeInput(const std::string& job_id, int frame, int stage) {
    const int64_t id = ParseJobId(job_id);
    std::lock_guard lock(mu_);
    JobRow job = LoadJob(id);
    std::optional<StageRow> row = store_.GetStage(id, frame, stage);
    if (!row)
        ThrowError(ErrorCode::kNotFound,
                   fmt::format("{} frame {} has no stage {}", job_id, frame, stage));
    StageMergeInput in;
    in.job_id = job_id;
    in.frame = frame;
    in.stage = stage;
    in.job_running = job.state == v1::JOB_STATE_RUNNING;
    in.merged = row->merged;
    in.ready = row->tasks_done == row->num_tasks;
    if (!in.job_running || in.merged || !in.ready) return in;
    const std::shared_ptr<const JobInfo> info = Info(id);
    in.plan = info->plan;
    if (stage >= static_cast<int>(in.plan->stages.size()) ||
        !in.plan->stages[stage].produces_artifact)
        ThrowError(ErrorCode::kInternal,
                   fmt::format("stage {} of {} produces no artifact", row->name, job_id));
    if (const int base = in.plan->stages[stage].extends; base >= 0) {
        std::optional<StageRow> extended = store_.GetStage(id, frame, base);
        if (!extended || !extended->merged)
            ThrowError(ErrorCode::kInternal,
                       fmt::format("{} frame {}: stage {} extends {}, which is not merged", job_id,
                                   frame, row->name, in.plan->stages[base].name));
        in.base_hash = extended->artifact_hash;
    }
    in.results = store_.StageResults(*row, &in.completions);
    return in;
}

void Scheduler::StageMerged(const std::string& job_id, int frame, int stage,
                            const std::string& hash, uint64_t size) {
    const int64_t id = ParseJobId(job_id);
    Events events;
    {
        std::lock_guard lock(mu_);
        JobRow job = LoadJob(id);
        if (job.state != v1::JOB_STATE_RUNNING) return;
        const std::shared_ptr<const JobInfo> info = Info(id);
        const std::vector<StagePlan>& plan = info->plan->stages;
        if (stage < 0 || stage >= static_cast<int>(plan.size()))
            ThrowError(ErrorCode::kInternal, fmt::format("{} has no stage {}", job_id, stage));
        SqliteTransaction txn(store_.Db());
        if (!store_.SetStageMerged(id, frame, stage, hash, size)) return;  // merged before
        // Release every later stage that reads this one and whose inputs are now all in.
        const std::vector<StageRow> rows = store_.GetFrameStages(id, frame);
        std::string released;
        for (size_t t = stage + 1; t < plan.size() && t < rows.size(); ++t) {
            const std::vector<int>& reads = plan[t].reads;
            if (std::find(reads.begin(), reads.end(), stage) == reads.end()) continue;
            bool ready = true;
            for (int r : reads) ready &= r < static_cast<int>(rows.size()) && rows[r].merged;
            if (!ready) continue;
            store_.ReleaseTasks(rows[t].first_task_id,
                                rows[t].first_task_id + rows[t].num_tasks - 1);
            released += (released.empty() ? "" : ", ") + plan[t].name;
        }
        {
            LogRow e;
            e.job_id = id;
            e.at_ms = clock_.NowMs();
            e.kind = "merged";
            e.frame = frame;
            e.stage = plan[stage].name;
            e.message =
                fmt::format("{} bytes{}{}", size, released.empty() ? "" : "; released ", released);
            store_.InsertLog(e);
        }
        txn.Commit();
        spdlog::info("job {} frame {}: {} merged into {} ({} bytes){}{}", job_id, frame,
                     plan[stage].name, hash.substr(0, 12), size,
                     released.empty() ? "" : "; now leasing ", released);
        events.push_back(
            {Event::kJob, job_id, fmt::format("frame {}: {} merged", frame, plan[stage].label)});
        if (!released.empty()) events.push_back({Event::kWork, job_id, ""});
    }
    Emit(events);
}

std::vector<std::tuple<std::string, int, int>> Scheduler::StagesAwaitingMerge() {
    std::lock_guard lock(mu_);
    std::vector<std::tuple<std::string, int, int>> out;
    for (const auto& [job, frame, stage] : store_.StagesAwaitingMerge())
        out.emplace_back(FormatJobId(job), frame, stage);
    return out;
}

std::vector<std::string> Scheduler::LiveBlobs() {
    std::lock_guard lock(mu_);
    return store_.LiveBlobHashes();
}

void Scheduler::FrameWritten(const std::string& job_id, int frame, const std::string& exr_path) {
    const int64_t id = ParseJobId(job_id);
    Events events;
    {
        std::lock_guard lock(mu_);
        JobRow job = LoadJob(id);
        SqliteTransaction txn(store_.Db());
        store_.SetFrameDone(id, frame, exr_path);
        const bool job_done =
            job.state == v1::JOB_STATE_RUNNING && store_.CountFramesNotDone(id) == 0;
        if (job_done) store_.SetJobState(id, v1::JOB_STATE_DONE, "", clock_.NowMs());
        {
            LogRow e;
            e.job_id = id;
            e.at_ms = clock_.NowMs();
            e.kind = "frame";
            e.frame = frame;
            e.message = "written to " + exr_path;
            store_.InsertLog(e);
        }
        if (job_done) Log(id, "job-done", nullptr, 0, "", 0, "");
        txn.Commit();
        spdlog::info("job {} frame {} written: {}", job_id, frame, exr_path);
        events.push_back({Event::kJob, job_id, fmt::format("frame {} done", frame)});
        if (job_done) {
            jobs_.erase(id);
            spdlog::info("job {} '{}' done", job_id, job.name);
            events.push_back({Event::kJob, job_id, "job done"});
        }
    }
    Emit(events);
}

void Scheduler::RequeueDoneTasks(const std::string& job_id, int frame, int stage,
                                 const std::vector<std::pair<int, int>>& tasks) {
    const int64_t id = ParseJobId(job_id);
    std::string name;
    {
        std::lock_guard lock(mu_);
        std::optional<StageRow> row = store_.GetStage(id, frame, stage);
        if (!row)
            ThrowError(ErrorCode::kNotFound,
                       fmt::format("{} frame {} has no stage {}", job_id, frame, stage));
        name = row->name;
        SqliteTransaction txn(store_.Db());
        int requeued = 0;
        for (const auto& [index, completions] : tasks)
            if (index >= 0 && index < row->num_tasks)
                requeued += store_.RequeueDoneTask(row->first_task_id + index, completions) ? 1 : 0;
        store_.UncountTasksDone(id, frame, stage, requeued);
        {
            LogRow e;
            e.job_id = id;
            e.at_ms = clock_.NowMs();
            e.kind = "requeued";
            e.frame = frame;
            e.stage = name;
            e.message =
                fmt::format("{} done task(s) whose results could not be read back", requeued);
            store_.InsertLog(e);
        }
        txn.Commit();
        spdlog::warn("job {} frame {}: {} finished {} task(s) re-queued", job_id, frame, requeued,
                     name);
    }
    Emit({{Event::kJob, job_id,
           fmt::format("frame {}: unreadable {} results re-queued", frame, name)},
          {Event::kWork, job_id, ""}});
}

void Scheduler::FailJob(const std::string& job_id, const std::string& message) {
    const int64_t id = ParseJobId(job_id);
    {
        std::lock_guard lock(mu_);
        JobRow job = LoadJob(id);
        if (IsFinished(job.state)) return;
        SqliteTransaction txn(store_.Db());
        EndJob(id, v1::JOB_STATE_FAILED, message);
        txn.Commit();
    }
    Emit({{Event::kJob, job_id, "job failed: " + message}});
}

std::vector<std::pair<std::string, int>> Scheduler::FramesAwaitingAssembly() {
    std::lock_guard lock(mu_);
    std::vector<std::pair<std::string, int>> out;
    for (const auto& [job, frame] : store_.FramesAwaitingAssembly())
        out.emplace_back(FormatJobId(job), frame);
    return out;
}

std::string Scheduler::FrameExrPath(const std::string& job_id, int frame) {
    const int64_t id = ParseJobId(job_id);
    std::lock_guard lock(mu_);
    LoadJob(id);
    std::optional<FrameRow> row = store_.GetFrame(id, frame);
    if (!row) ThrowError(ErrorCode::kNotFound, fmt::format("{} has no frame {}", job_id, frame));
    if (row->state != v1::FRAME_STATE_DONE || row->exr_path.empty())
        ThrowError(ErrorCode::kNotFound,
                   fmt::format("frame {} of {} is not done yet", frame, job_id));
    return row->exr_path;
}

void Scheduler::Log(int64_t job_id, const char* kind, const TaskRow* task, int64_t first_task_id,
                    const std::string& worker, int attempt, const std::string& message,
                    const std::string& log_tail, int64_t leased_ms) {
    LogRow e;
    e.job_id = job_id;
    e.at_ms = clock_.NowMs();
    e.kind = kind;
    if (task) {
        e.frame = task->frame;
        e.stage = task->stage;
        e.task_index = task->task_index;
        e.task = task->id - first_task_id;
    }
    e.worker = worker;
    e.attempt = attempt;
    e.message = Truncate(message);
    e.log_tail = log_tail;
    e.leased_ms = leased_ms;
    store_.InsertLog(e);
}

v1::WorkerStatus Scheduler::SetWorkerEnabled(const std::string& worker, bool enabled) {
    std::lock_guard lock(mu_);
    // By name (the oldest worker of that name, as RegisterWorker) or by id.
    int64_t id = 0;
    for (const auto& [known_id, w] : workers_)
        if (w.name == worker && (id == 0 || known_id < id)) id = known_id;
    if (id == 0 && worker.rfind("w-", 0) == 0) {
        int64_t parsed = 0;
        auto [ptr, ec] = std::from_chars(worker.data() + 2, worker.data() + worker.size(), parsed);
        if (ec == std::errc() && ptr == worker.data() + worker.size() && workers_.count(parsed))
            id = parsed;
    }
    if (id == 0)
        ThrowError(ErrorCode::kNotFound,
                   fmt::format("no worker named '{}' (tessera workers lists them)",
                               worker.substr(0, 256)));
    Worker& w = workers_[id];
    if (w.disabled != !enabled) {
        SqliteTransaction txn(store_.Db());
        store_.SetWorkerDisabled(id, !enabled);
        txn.Commit();
        w.disabled = !enabled;
        spdlog::info("worker '{}' ({}) {}", w.name, FormatWorkerId(id),
                     enabled ? "enabled: it takes tasks again"
                             : "disabled: it finishes the tasks it holds and takes no new ones");
    }
    if (enabled && listener_) listener_->OnWorkAvailable();
    return WorkerStatusOf(id, w, clock_.NowMs());
}

std::vector<StageTaskCounts> Scheduler::TaskCountsByStage() {
    std::lock_guard lock(mu_);
    std::vector<StageTaskCounts> out;
    for (int64_t id : store_.JobIds()) {
        const std::optional<int> state = store_.JobState(id);
        if (!state || IsFinished(*state)) continue;
        const std::shared_ptr<const JobInfo> info = Info(id);
        for (const auto& row : store_.TaskCountsByStage(
                 info->first_task_id, info->first_task_id + info->tasks_total - 1)) {
            const std::string& stage = row.first;
            const std::array<int64_t, 5>& counts = row.second;
            auto it = std::find_if(out.begin(), out.end(),
                                   [&](const StageTaskCounts& c) { return c.stage == stage; });
            if (it == out.end()) {
                out.push_back({stage});
                it = out.end() - 1;
            }
            it->pending += counts[int(TaskState::kPending)];
            it->leased += counts[int(TaskState::kLeased)];
            it->done += counts[int(TaskState::kDone)];
            it->waiting += counts[int(TaskState::kWaiting)];
        }
    }
    return out;
}

SchedulerCounters Scheduler::Counters() {
    std::lock_guard lock(mu_);
    return counters_;
}

v1::JobStatus Scheduler::SetPriority(const std::string& job_id, int priority) {
    const int64_t id = ParseJobId(job_id);
    v1::JobStatus status;
    int old = 0;
    {
        std::lock_guard lock(mu_);
        const JobRow job = LoadJob(id);
        if (IsFinished(job.state))
            ThrowError(ErrorCode::kFailedPrecondition,
                       fmt::format("{} is {}: its priority no longer matters", job_id,
                                   v1::JobState_Name(job.state)));
        old = job.priority;
        SqliteTransaction txn(store_.Db());
        store_.SetJobPriority(id, priority);
        Log(id, "priority", nullptr, 0, "", 0, fmt::format("priority {} -> {}", old, priority));
        txn.Commit();
        spdlog::info("job {} '{}': priority {} -> {}", job_id, job.name, old, priority);
        status = BuildStatus(id);
    }
    Emit({{Event::kJob, job_id, fmt::format("priority {} -> {}", old, priority)},
          {Event::kWork, job_id, ""}});
    return status;
}

v1::JobStatus Scheduler::Retry(const std::string& job_id) {
    const int64_t id = ParseJobId(job_id);
    v1::JobStatus status;
    Events events;
    {
        std::lock_guard lock(mu_);
        const JobRow job = LoadJob(id);
        if (job.state == v1::JOB_STATE_DONE)
            ThrowError(ErrorCode::kFailedPrecondition,
                       job_id + " is done: every frame is written, nothing to retry");
        if (!IsFinished(job.state))
            ThrowError(
                ErrorCode::kFailedPrecondition,
                fmt::format("{} is still {}: only a failed or cancelled job can be "
                            "retried",
                            job_id, job.state == v1::JOB_STATE_QUEUED ? "queued" : "running"));
        jobs_.erase(id);
        const std::shared_ptr<const JobInfo> info = Info(id);
        const std::vector<StagePlan>& plan = info->plan->stages;
        SqliteTransaction txn(store_.Db());
        store_.ReopenJob(id);
        int reopened = 0, frames = 0;
        std::vector<std::pair<int, int>> merges;  // (frame, stage) done but never merged
        std::vector<int> assemblies;              // frames done but never written
        for (const FrameRow& f : store_.GetFrames(id)) {
            if (f.state == v1::FRAME_STATE_DONE) continue;
            ++frames;
            const std::vector<StageRow> rows = store_.GetFrameStages(id, f.frame);
            for (const StageRow& row : rows) {
                bool inputs_in = true;
                if (row.index < static_cast<int>(plan.size()))
                    for (int r : plan[row.index].reads)
                        inputs_in &= r < static_cast<int>(rows.size()) && rows[r].merged;
                reopened +=
                    store_.ReopenTasks(row.first_task_id, row.first_task_id + row.num_tasks - 1,
                                       inputs_in ? TaskState::kPending : TaskState::kWaiting);
                if (row.produces_artifact && !row.merged && row.tasks_done == row.num_tasks)
                    merges.emplace_back(f.frame, row.index);
            }
            if (f.tasks_done == f.tasks_total) assemblies.push_back(f.frame);
        }
        Log(id, "retried", nullptr, 0, "", 0,
            fmt::format("{} frame(s) re-opened, {} task(s) queued again", frames, reopened));
        txn.Commit();
        spdlog::info("job {} '{}' retried: {} frame(s) re-opened, {} task(s) queued again", job_id,
                     job.name, frames, reopened);
        status = BuildStatus(id);
        events.push_back({Event::kJob, job_id, "job retried"});
        events.push_back({Event::kWork, job_id, ""});
        for (const auto& [frame, stage] : merges)
            events.push_back({Event::kStageReady, job_id, "", frame, stage});
        for (int frame : assemblies) events.push_back({Event::kFrameReady, job_id, "", frame});
    }
    Emit(events);
    return status;
}

DeletedJob Scheduler::Delete(const std::string& job_id) {
    const int64_t id = ParseJobId(job_id);
    DeletedJob deleted;
    {
        std::lock_guard lock(mu_);
        const JobRow job = LoadJob(id);
        SqliteTransaction txn(store_.Db());
        if (!IsFinished(job.state)) EndJob(id, v1::JOB_STATE_CANCELLED, "");
        store_.DeleteJob(id, &deleted.inputs, &deleted.outputs);
        txn.Commit();
        jobs_.erase(id);
        spdlog::info("job {} '{}' deleted", job_id, job.name);
    }
    Emit({{Event::kJob, job_id, "job deleted"}});
    return deleted;
}

std::vector<v1::JobLogEntry> Scheduler::JobLog(const std::string& job_id,
                                               std::optional<int64_t> task, int limit) {
    const int64_t id = ParseJobId(job_id);
    std::lock_guard lock(mu_);
    const JobRow job = LoadJob(id);
    if (task && (*task < 0 || *task >= job.tasks_total))
        ThrowError(ErrorCode::kInvalidArgument,
                   fmt::format("{} has tasks 0..{}; there is no task {}", job_id,
                               job.tasks_total - 1, *task));
    if (limit <= 0) limit = 1000;
    std::vector<v1::JobLogEntry> out;
    for (const LogRow& r : store_.JobLog(id, task, std::min(limit, 100000))) {
        v1::JobLogEntry& e = out.emplace_back();
        e.set_at_unix_ms(r.at_ms);
        e.set_kind(r.kind);
        e.set_frame(r.frame);
        e.set_stage(r.stage);
        e.set_task_index(r.task_index);
        e.set_task(r.task);
        e.set_worker(r.worker);
        e.set_attempt(r.attempt);
        e.set_message(r.message);
        e.set_log_tail(r.log_tail);
        e.set_leased_unix_ms(r.leased_ms);
    }
    return out;
}

std::vector<std::string> Scheduler::JobsFinishedBefore(int64_t ms) {
    std::lock_guard lock(mu_);
    std::vector<std::string> out;
    for (int64_t id : store_.JobsFinishedBefore(ms)) out.push_back(FormatJobId(id));
    return out;
}

}  // namespace tessera
