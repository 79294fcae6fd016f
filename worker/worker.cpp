#include "worker.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <iterator>
#include <stdexcept>
#include <thread>
#include <vector>

#include "backoff.h"
#include "blob_client.h"
#include "log_tail.h"
#include "plan/render_plan.h"
#include "scene/ray_counter.h"
#include "task_samples.h"

namespace tessera {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

struct Worker::Active {
    v1::Task task;
    Clock::time_point leased_at = Clock::now();
    std::atomic<bool> abandoned{false};  // lease lost or job cancelled: drop the result
    // Completing or failing it is under way: the answer to that call is the last word,
    // and a heartbeat racing with it would only find the lease already released.
    std::atomic<bool> reporting{false};
    std::atomic<float> progress{0};
    // Where its log lines come from (LogTail::Lines): set when its render thread starts it.
    spdlog::log_clock::time_point started;
    size_t thread = 0;
};

namespace {

constexpr size_t kMaxFailureMessage = 4096;
// How long a task's calls are retried while the coordinator is unreachable, and how
// long after a stop request.
constexpr auto kMaxRetry = std::chrono::minutes(10);
constexpr auto kStopGrace = std::chrono::seconds(10);

// The coordinator is down, restarting or too slow: worth trying again. (A coordinator
// shutting down answers pending calls with CANCELLED; the worker's own cancellations
// happen only on Stop(), which is checked first.)
bool IsTransient(grpc::StatusCode code) {
    return code == grpc::StatusCode::UNAVAILABLE || code == grpc::StatusCode::DEADLINE_EXCEEDED ||
           code == grpc::StatusCode::CANCELLED;
}

// The blob client reports errors as exceptions whose text is its own words and then
// StatusText ("CODE: message"); this recovers whether the cause was transient. Only
// for the blob client's messages: a scene loader's could quote anything.
bool IsTransientText(const std::string& text) {
    for (const char* code : {"UNAVAILABLE: ", "DEADLINE_EXCEEDED: ", "CANCELLED: "})
        if (text.find(code) != std::string::npos) return true;
    return text.find("RESOURCE_EXHAUSTED: ") != std::string::npos && Worker::CoordinatorBusy(text);
}

template <typename Rep, typename Period>
void SetDeadline(grpc::ClientContext& ctx, std::chrono::duration<Rep, Period> d) {
    ctx.set_deadline(std::chrono::system_clock::now() + d);
}

std::string Describe(const v1::Task& t) {
    return fmt::format("task {} (job {}, frame {}, {} {}, attempt {})", t.task_id(), t.job_id(),
                       t.frame(), t.stage(), t.task_index(), t.attempt());
}

std::string ReadWholeFile(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open " + path.string());
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw std::runtime_error("cannot read " + path.string());
    return bytes;
}

long long Ms(Clock::duration d) { return std::chrono::duration_cast<milliseconds>(d).count(); }

}  // namespace

Worker::Worker(WorkerOptions options, v1::Workers::StubInterface& workers,
               v1::BlobStore::StubInterface& blobs)
    : options_(std::move(options)), workers_(workers), blobs_(blobs) {
    options_.threads = std::max(1, options_.threads);
    // Bundles of a previous run are stale; blobs are content-addressed and stay valid.
    fs::remove_all(options_.cache_dir / "jobs");
    blob_cache_ = std::make_unique<BlobCache>(
        options_.cache_dir / "blobs",
        [this](const std::string& hash) {
            try {
                return DownloadBlob(blobs_, hash);
            } catch (const std::exception& e) {
                throw BlobFetchError(e.what(), IsTransientText(e.what()));
            }
        },
        options_.blob_cache_bytes);
    scene_cache_ = std::make_unique<SceneCache>(options_.cache_dir / "jobs", *blob_cache_,
                                                options_.cached_jobs, /*max_frames=*/4,
                                                options_.artifact_cache_bytes);
}

Worker::~Worker() = default;

void Worker::Run() {
    // Before the threads below log: it replaces the default logger.
    log_tail_ = &InstallLogTail();
    {
        std::lock_guard lock(registering_mutex_);
        if (!Register(true)) return;
    }
    std::vector<std::thread> renderers;
    for (int i = 0; i < options_.threads; ++i) renderers.emplace_back([this] { RenderLoop(); });
    std::thread heartbeats([this] { HeartbeatLoop(); });

    LeaseLoop();
    {
        std::lock_guard lock(tasks_mutex_);
        leasing_done_ = true;
        if (!active_.empty())
            spdlog::info("stopping: finishing {} task(s) in flight", active_.size());
    }
    tasks_cv_.notify_all();
    for (std::thread& t : renderers) t.join();
    {
        std::lock_guard lock(tasks_mutex_);
        heartbeats_done_ = true;
    }
    tasks_cv_.notify_all();
    heartbeats.join();
    spdlog::info("stopped: {} task(s) completed, {} failed, {} dropped", completed_.load(),
                 failed_.load(), dropped_.load());
}

void Worker::Stop() {
    if (stopping_) return;
    stop_requested_ = Clock::now().time_since_epoch().count();
    if (stopping_.exchange(true)) return;
    { std::lock_guard lock(tasks_mutex_); }  // a waiter is either asleep or sees the flag
    tasks_cv_.notify_all();
    std::lock_guard lock(lease_mutex_);
    if (lease_call_) lease_call_->TryCancel();
}

bool Worker::Register(bool first) {
    Backoff backoff;
    while (!stopping_) {
        grpc::ClientContext ctx;
        SetDeadline(ctx, std::chrono::seconds(10));
        v1::RegisterRequest req;
        req.set_name(options_.name);
        req.set_threads(options_.threads);
        v1::RegisterResponse resp;
        grpc::Status st = workers_.Register(&ctx, req, &resp);
        if (st.ok()) {
            std::lock_guard lock(register_mutex_);
            worker_id_ = resp.worker_id();
            if (resp.heartbeat_interval_ms() > 0)
                heartbeat_interval_ = milliseconds(resp.heartbeat_interval_ms());
            spdlog::info(
                "registered as '{}' (worker id {}): {} thread(s), heartbeat every {} ms, leases "
                "of {} ms",
                options_.name, worker_id_, options_.threads, heartbeat_interval_.count(),
                resp.lease_duration_ms());
            return true;
        }
        milliseconds delay = backoff.Next();
        if (IsTransient(st.error_code())) {
            spdlog::warn("coordinator unreachable ({}); reconnecting in {} ms", StatusText(st),
                         delay.count());
        } else if (first) {
            // A refusal at start-up (a name in use, a bad request) is the user's to fix.
            throw std::runtime_error("the coordinator refused to register this worker: " +
                                     StatusText(st));
        } else {
            spdlog::error("registration refused ({}); retrying in {} ms", StatusText(st),
                          delay.count());
        }
        ResetConnection();
        SleepUnlessStopped(delay);
    }
    return false;
}

void Worker::Reregister(const std::string& stale_id) {
    std::lock_guard lock(registering_mutex_);
    if (WorkerId() != stale_id) return;  // another thread registered meanwhile
    spdlog::warn("the coordinator does not know worker id {} (restarted?); registering again",
                 stale_id);
    Register(false);
}

std::string Worker::WorkerId() const {
    std::lock_guard lock(register_mutex_);
    return worker_id_;
}

milliseconds Worker::HeartbeatInterval() const {
    std::lock_guard lock(register_mutex_);
    return heartbeat_interval_;
}

bool Worker::KeepRetrying(const Active& task, Clock::time_point start, milliseconds delay) const {
    // A restarted coordinator recovers its leases, so a result is worth keeping while the
    // coordinator is away; the heartbeats say when the lease is gone.
    if (task.abandoned) return false;
    Clock::time_point next = Clock::now() + delay;
    if (next > start + kMaxRetry) return false;
    return !stopping_ ||
           next < Clock::time_point(Clock::duration(stop_requested_.load())) + kStopGrace;
}

void Worker::ResetConnection() {
    if (options_.reset_connection) options_.reset_connection();
}

bool Worker::SleepUnlessStopped(milliseconds d) {
    std::unique_lock lock(tasks_mutex_);
    return !tasks_cv_.wait_for(lock, d, [this] { return stopping_.load(); });
}

void Worker::LeaseLoop() {
    Backoff backoff;
    while (!stopping_) {
        const uint64_t reconnects = reconnects_;
        {
            // Lease only for a render thread that would start the task at once.
            std::unique_lock lock(tasks_mutex_);
            tasks_cv_.wait(lock, [this] {
                return stopping_ || idle_threads_ > static_cast<int>(queue_.size());
            });
        }
        std::string id = WorkerId();
        grpc::ClientContext ctx;
        SetDeadline(ctx, milliseconds(options_.lease_wait_ms) + std::chrono::seconds(10));
        {
            std::lock_guard lock(lease_mutex_);
            if (stopping_) break;
            lease_call_ = &ctx;
        }
        v1::LeaseTaskRequest req;
        req.set_worker_id(id);
        req.set_wait_ms(options_.lease_wait_ms);
        v1::LeaseTaskResponse resp;
        grpc::Status st = workers_.LeaseTask(&ctx, req, &resp);
        {
            std::lock_guard lock(lease_mutex_);
            lease_call_ = nullptr;
        }
        if (st.ok()) {
            backoff.Reset();
            if (!resp.has_task()) continue;
            auto active = std::make_shared<Active>();
            active->task = std::move(*resp.mutable_task());
            spdlog::info("leased {}", Describe(active->task));
            {
                std::lock_guard lock(tasks_mutex_);
                active_[active->task.lease_id()] = active;
                queue_.push_back(std::move(active));
            }
            tasks_cv_.notify_all();
            continue;
        }
        // Cancelled by Stop(): a task granted in that instant is never seen here, and its
        // lease simply expires on the coordinator.
        if (stopping_) break;
        milliseconds delay = backoff.Next();
        if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
            Reregister(id);  // then a short pause: never a tight loop, whatever the cause
        } else if (IsTransient(st.error_code())) {
            spdlog::warn("coordinator unreachable ({}); reconnecting in {} ms", StatusText(st),
                         delay.count());
            ResetConnection();
        } else {
            spdlog::error("leasing failed ({}); retrying in {} ms", StatusText(st), delay.count());
        }
        std::unique_lock lock(tasks_mutex_);
        tasks_cv_.wait_for(lock, delay, [&] { return stopping_ || reconnects_ != reconnects; });
    }
}

void Worker::RenderLoop() {
    ScratchBuffer arena;
    std::unique_lock lock(tasks_mutex_);
    while (true) {
        ++idle_threads_;
        tasks_cv_.notify_all();
        tasks_cv_.wait(lock, [this] { return !queue_.empty() || leasing_done_; });
        --idle_threads_;
        if (queue_.empty()) return;
        std::shared_ptr<Active> task = std::move(queue_.front());
        queue_.pop_front();
        lock.unlock();
        RunTask(task, arena);
        lock.lock();
        active_.erase(task->task.lease_id());
    }
}

void Worker::HeartbeatLoop() {
    bool failing = false;
    while (true) {
        std::vector<std::shared_ptr<Active>> tasks;
        {
            std::unique_lock lock(tasks_mutex_);
            if (tasks_cv_.wait_for(lock, HeartbeatInterval(), [this] { return heartbeats_done_; }))
                return;
            for (auto& [lease, task] : active_)
                if (!task->reporting) tasks.push_back(task);
        }
        if (tasks.empty()) tasks.push_back(nullptr);  // idle: the worker itself is alive
        for (const auto& task : tasks) {
            grpc::Status st = Heartbeat(task);
            if (st.ok() && failing) {
                spdlog::info("heartbeats reach the coordinator again");
                ++reconnects_;
                tasks_cv_.notify_all();  // the lease loop need not wait out its backoff
            }
            if (!st.ok() && !failing) spdlog::warn("heartbeat failed: {}", StatusText(st));
            if (IsTransient(st.error_code())) ResetConnection();
            failing = !st.ok();
        }
    }
}

grpc::Status Worker::Heartbeat(const std::shared_ptr<Active>& task) {
    std::string id = WorkerId();
    grpc::ClientContext ctx;
    SetDeadline(ctx, std::max<milliseconds>(HeartbeatInterval(), std::chrono::seconds(1)));
    v1::HeartbeatRequest req;
    req.set_worker_id(id);
    if (task) {
        req.set_task_id(task->task.task_id());
        req.set_lease_id(task->task.lease_id());
        req.set_lease_token(task->task.lease_token());
        req.set_progress(task->progress.load());
    }
    req.set_samples_done(samples_done_.load());
    req.set_rays_traced(RaysTraced());
    v1::HeartbeatResponse resp;
    grpc::Status st = workers_.Heartbeat(&ctx, req, &resp);
    if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
        Reregister(id);
        return grpc::Status::OK;  // not a failure of the connection
    }
    if (st.error_code() == grpc::StatusCode::PERMISSION_DENIED && task) {
        // The lease is not ours (e.g. we registered again under a new id since).
        if (!task->reporting && !task->abandoned.exchange(true))
            spdlog::warn("{}: the coordinator refuses our lease ({}); abandoning it",
                         Describe(task->task), StatusText(st));
        return grpc::Status::OK;
    }
    if (st.ok() && task && (resp.cancelled() || !resp.lease_valid()) && !task->reporting &&
        !task->abandoned.exchange(true)) {
        spdlog::warn("{}: {}; abandoning it", Describe(task->task),
                     resp.cancelled() ? "its job was cancelled" : "the lease is no longer valid");
    }
    return st;
}

bool Worker::Dropped(const Active& task, const char* when) {
    if (!task.abandoned) return false;
    spdlog::info("{}: dropped {}", Describe(task.task), when);
    ++dropped_;
    return true;
}

void Worker::RunTask(const std::shared_ptr<Active>& task, ScratchBuffer& arena) {
    const v1::Task& t = task->task;
    task->started = spdlog::log_clock::now();
    task->thread = LogTail::ThisThread();
    std::shared_ptr<const FrameRenderer> renderer;
    int stage = -1;
    ArtifactSet artifacts;
    try {
        // Their messages name the step that failed.
        renderer = WithFetchRetry(
            *task, [&] { return scene_cache_->Renderer(t.job_id(), t.spec(), t.frame()); });
        stage = StageOf(*renderer, t);
        artifacts = LoadInputs(*task, *renderer, stage);
    } catch (const std::exception& e) {
        Fail(*task, e.what());
        return;
    } catch (...) {
        Fail(*task, "preparing the task failed: unknown error");
        return;
    }
    if (Dropped(*task, "before rendering")) return;
    std::string result;
    try {
        arena.Reset();
        result = renderer->RunTask(stage, t.task_index(), artifacts, arena);
        samples_done_ += SamplesOfTask(renderer->Plan(), stage, t.task_index());
    } catch (const std::exception& e) {
        Fail(*task,
             fmt::format("running {} task {} failed: {}", t.stage(), t.task_index(), e.what()));
        return;
    } catch (...) {
        Fail(*task,
             fmt::format("running {} task {} failed: unknown error", t.stage(), t.task_index()));
        return;
    }
    task->progress = 1;
    Complete(*task, result);
}

int Worker::StageOf(const FrameRenderer& renderer, const v1::Task& t) {
    const RenderPlan& plan = renderer.Plan();
    const int stage = plan.StageIndex(t.stage());
    if (stage < 0) {
        std::string names;
        for (const StagePlan& s : plan.stages) names += (names.empty() ? "" : ", ") + s.name;
        throw std::runtime_error(fmt::format(
            "invalid task: stage '{}' is not in the frame's render plan (its stages: {})",
            t.stage(), names));
    }
    return stage;
}

ArtifactSet Worker::LoadInputs(const Active& task, const FrameRenderer& renderer, int stage) {
    const v1::Task& t = task.task;
    const RenderPlan& plan = renderer.Plan();
    ArtifactSet artifacts(plan.stages.size());
    for (const v1::TaskInput& input : t.inputs()) {
        const int s = plan.StageIndex(input.stage());
        if (s < 0 || !plan.stages[s].produces_artifact)
            throw std::runtime_error(fmt::format(
                "invalid task: input '{}' names no artifact stage of the plan", input.stage()));
        artifacts[s] = WithFetchRetry(task, [&] {
            return scene_cache_->GetArtifact(t.job_id(), t.spec(), t.frame(), s, input.hash(), [&] {
                try {
                    return ReadWholeFile(blob_cache_->Ensure(input.hash(), input.size()));
                } catch (const BlobFetchError& e) {
                    throw BlobFetchError(
                        fmt::format("fetching the {} artifact failed: {}", input.stage(), e.what()),
                        e.Transient());
                }
            });
        });
    }
    for (int r : plan.stages[stage].reads)
        if (!artifacts[r])
            throw std::runtime_error(
                fmt::format("invalid task: stage {} reads the {} artifact, which the task does "
                            "not name",
                            t.stage(), plan.stages[r].name));
    return artifacts;
}

template <typename F>
auto Worker::WithFetchRetry(const Active& task, const F& step) -> decltype(step()) {
    const v1::Task& t = task.task;
    Backoff backoff;
    const Clock::time_point start = Clock::now();
    while (true) {
        try {
            return step();
        } catch (const BlobFetchError& e) {
            // A coordinator that is away is no fault of the task: wait for it rather than
            // spend one of the task's attempts.
            milliseconds delay = backoff.Next();
            if (!e.Transient() || !KeepRetrying(task, start, delay)) throw;
            ResetConnection();
            spdlog::warn("{}: {}; retrying in {} ms", Describe(t), e.what(), delay.count());
            std::this_thread::sleep_for(delay);
        }
    }
}

void Worker::Complete(Active& task, const std::string& result) {
    const v1::Task& t = task.task;
    if (Dropped(task, "after rendering")) return;
    // Small results travel inline with CompleteTask; larger ones are uploaded first.
    const bool inline_result = !result.empty() && result.size() <= kMaxInlineResultBytes;
    std::string hash;
    grpc::Status st;
    if (!inline_result) {
        st = CallWithRetry("uploading the result", task, [&] {
            try {
                hash = UploadBlob(blobs_, result);
                return grpc::Status::OK;
            } catch (const std::exception& e) {
                return grpc::Status(IsTransientText(e.what()) ? grpc::StatusCode::UNAVAILABLE
                                                              : grpc::StatusCode::UNKNOWN,
                                    e.what());
            }
        });
    }
    if (!st.ok()) {
        if (IsTransient(st.error_code()) || task.abandoned) {
            spdlog::warn("{}: giving up on its result ({})", Describe(t), st.error_message());
            ++dropped_;
        } else {
            Fail(task, "uploading the result failed: " + st.error_message());
        }
        return;
    }
    if (Dropped(task, "after uploading")) return;
    task.reporting = true;
    st = CallAsWorker("completing the task", task, [&](const std::string& worker_id) {
        grpc::ClientContext ctx;
        SetDeadline(ctx, std::chrono::seconds(30));
        v1::CompleteTaskRequest req;
        req.set_worker_id(worker_id);
        req.set_task_id(t.task_id());
        req.set_lease_id(t.lease_id());
        req.set_lease_token(t.lease_token());
        if (inline_result)
            req.set_result(result);
        else
            req.set_result_hash(hash);
        v1::CompleteTaskResponse resp;
        return workers_.CompleteTask(&ctx, req, &resp);
    });
    if (st.ok()) {
        spdlog::info("completed {} in {} ms", Describe(t), Ms(Clock::now() - task.leased_at));
        ++completed_;
    } else if (st.error_code() == grpc::StatusCode::FAILED_PRECONDITION) {
        spdlog::warn("{}: the lease is stale ({}); result dropped", Describe(t), StatusText(st));
        ++dropped_;
    } else {
        spdlog::error("{}: completion refused ({}); result dropped", Describe(t), StatusText(st));
        ++dropped_;
    }
}

void Worker::Fail(Active& task, std::string message) {
    const v1::Task& t = task.task;
    if (message.size() > kMaxFailureMessage) message.resize(kMaxFailureMessage);
    // Before the line below, which says what the message says.
    const std::string log_tail =
        log_tail_ ? log_tail_->Lines(task.started, task.thread, Describe(t)) : std::string();
    spdlog::error("{} failed: {}", Describe(t), message);
    ++failed_;
    if (task.abandoned) return;  // the lease is gone: nobody would accept the report
    task.reporting = true;
    grpc::Status st =
        CallAsWorker("reporting the failure", task, [&](const std::string& worker_id) {
            grpc::ClientContext ctx;
            SetDeadline(ctx, std::chrono::seconds(30));
            v1::FailTaskRequest req;
            req.set_worker_id(worker_id);
            req.set_task_id(t.task_id());
            req.set_lease_id(t.lease_id());
            req.set_lease_token(t.lease_token());
            req.set_message(message);
            req.set_log_tail(log_tail);
            v1::FailTaskResponse resp;
            return workers_.FailTask(&ctx, req, &resp);
        });
    if (!st.ok())
        spdlog::warn("{}: the failure could not be reported ({})", Describe(t), StatusText(st));
}

bool Worker::CoordinatorBusy(const std::string& message) {
    return message.find("no space left on ") != std::string::npos ||
           message.find("too many ") != std::string::npos;
}

grpc::Status Worker::CallWithRetry(const char* what, const Active& task,
                                   const std::function<grpc::Status()>& call) {
    Backoff backoff;
    const Clock::time_point start = Clock::now();
    while (true) {
        grpc::Status st = call();
        // A coordinator out of disk space, or at its limit of open streams, keeps the
        // lease alive meanwhile: the result is worth keeping, as while it is unreachable.
        const bool busy = st.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED &&
                          CoordinatorBusy(st.error_message());
        if (st.ok() || (!IsTransient(st.error_code()) && !busy)) return st;
        milliseconds delay = backoff.Next();
        if (!KeepRetrying(task, start, delay)) return st;
        ResetConnection();
        spdlog::warn("{}: {}: coordinator {} ({}); retrying in {} ms", Describe(task.task), what,
                     busy ? "busy" : "unreachable", StatusText(st), delay.count());
        std::this_thread::sleep_for(delay);
    }
}

grpc::Status Worker::CallAsWorker(const char* what, const Active& task,
                                  const std::function<grpc::Status(const std::string&)>& call) {
    std::string id = WorkerId();
    grpc::Status st = CallWithRetry(what, task, [&] { return call(id); });
    if (st.error_code() != grpc::StatusCode::NOT_FOUND || !IsUnknownWorker(id)) return st;
    // The coordinator knows us no more (its state was lost): a lease is held by the
    // worker id it was given to, so the call will most likely be refused, but try once.
    Reregister(id);
    id = WorkerId();
    return CallWithRetry(what, task, [&] { return call(id); });
}

bool Worker::IsUnknownWorker(const std::string& worker_id) {
    grpc::ClientContext ctx;
    SetDeadline(ctx, std::chrono::seconds(10));
    v1::HeartbeatRequest req;
    req.set_worker_id(worker_id);
    v1::HeartbeatResponse resp;
    return workers_.Heartbeat(&ctx, req, &resp).error_code() == grpc::StatusCode::NOT_FOUND;
}

}  // namespace tessera
