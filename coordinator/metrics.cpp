#include "metrics.h"

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <functional>
#include <iterator>
#include <map>
#include <mutex>
#include <set>

#include "coordinator.h"
#include "dashboard_json.h"

namespace tessera {

namespace {

using prometheus::BuildCounter;
using prometheus::BuildGauge;
using prometheus::BuildHistogram;
using prometheus::Counter;
using prometheus::Family;
using prometheus::Gauge;
using prometheus::Histogram;

constexpr const char* kJobStates[] = {"queued", "running", "done", "failed", "cancelled"};
// The task states of StageTaskCounts, by their label.
constexpr const char* kTaskStates[] = {"waiting", "pending", "leased", "done"};
// WorkerStatus.state's words; a state not among them still gets its own series.
constexpr const char* kWorkerStates[] = {"idle",   "busy",     "put aside",
                                         "silent", "disabled", "draining"};

// Frame writes take from milliseconds (a small preview) to minutes (a large EXR with
// many AOVs and splat buffers); merges similarly (a photon map, an irradiance cache).
const Histogram::BucketBoundaries kWorkBuckets = {0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5,
                                                  1,     2.5,  5,     10,   30,  60,   120};

// Brings a counter up to `total`, a count kept elsewhere since the coordinator started.
void AdvanceTo(Counter& counter, double total) {
    const double now = counter.Value();
    if (total > now) counter.Increment(total - now);
}

// The series of one gauge family keyed by one label, for values read afresh at each
// scrape: keys not seen in a refresh are removed (a worker that is gone), or set to 0
// when `keep` (a state or stage that is merely empty now).
class KeyedGauges {
  public:
    KeyedGauges(Family<Gauge>& family, std::string label, bool keep)
        : family_(family), label_(std::move(label)), keep_(keep) {}

    // Starts a refresh: every key is unset until Set again.
    void Begin() { seen_.clear(); }
    void Set(const std::string& key, double value) {
        auto it = gauges_.find(key);
        if (it == gauges_.end()) it = gauges_.emplace(key, &family_.Add({{label_, key}})).first;
        it->second->Set(value);
        seen_.insert(key);
    }
    // Ends a refresh: the keys not set are zeroed or removed.
    void End() {
        for (auto it = gauges_.begin(); it != gauges_.end();) {
            if (seen_.count(it->first)) {
                ++it;
            } else if (keep_) {
                it->second->Set(0);
                ++it;
            } else {
                family_.Remove(it->second);
                it = gauges_.erase(it);
            }
        }
    }

  private:
    Family<Gauge>& family_;
    std::string label_;
    bool keep_;
    std::map<std::string, Gauge*> gauges_;
    std::set<std::string> seen_;
};

}  // namespace

struct FarmMetrics::Impl {
    explicit Impl(Coordinator& c);
    ~Impl();

    void Refresh();
    // Runs one part of the refresh; an error is logged and counted, and the other parts
    // still run (a full disk may fail the database reads, not the blob count).
    void RefreshPart(const char* part, const std::function<void()>& refresh);
    void RefreshTasks();
    void RefreshCounters();
    void RefreshJobs();
    void RefreshWorkers();
    void RefreshFarm();
    void OnFrameWork(const FrameWorkTiming& timing);

    Coordinator& coordinator;
    prometheus::Registry registry;
    std::mutex mu;  // one refresh at a time

    Family<Gauge>& tasks;
    Family<Counter>& tasks_completed;
    Family<Counter>& tasks_failed;
    Family<Counter>& lease_expiries;
    Counter& leases_granted;
    Family<Gauge>& jobs;
    Family<Gauge>& workers;
    KeyedGauges worker_samples_per_second;
    KeyedGauges worker_rays_per_second;
    KeyedGauges worker_tasks_leased;
    KeyedGauges worker_last_seen;
    Gauge& blob_bytes;
    Gauge& blob_count;
    Histogram& frame_assembly;
    Family<Histogram>& stage_merge;
    Gauge& farm_problem;
    Gauge& queued_tasks;
    Family<Counter>& refresh_errors;

    // (stage, state) series of `tasks` set so far: zeroed when the stage has no tasks.
    std::map<std::pair<std::string, std::string>, Gauge*> task_gauges;
};

namespace {

Family<Gauge>& GaugeFamily(prometheus::Registry& r, const char* name, const char* help) {
    return BuildGauge().Name(name).Help(help).Register(r);
}
Family<Counter>& CounterFamily(prometheus::Registry& r, const char* name, const char* help) {
    return BuildCounter().Name(name).Help(help).Register(r);
}

}  // namespace

FarmMetrics::Impl::Impl(Coordinator& c)
    : coordinator(c),
      tasks(GaugeFamily(registry, "tessera_tasks",
                        "Tasks of queued and running jobs, by stage and state (waiting: for "
                        "the artifacts of earlier stages; pending: ready to lease; leased; done)")),
      tasks_completed(CounterFamily(registry, "tessera_tasks_completed_total",
                                    "Tasks completed since the coordinator started, by stage")),
      tasks_failed(CounterFamily(registry, "tessera_tasks_failed_total",
                                 "Task failures reported by workers since the coordinator "
                                 "started, by stage")),
      lease_expiries(CounterFamily(registry, "tessera_lease_expiries_total",
                                   "Leases that expired (their worker went silent) since the "
                                   "coordinator started, by stage")),
      leases_granted(CounterFamily(registry, "tessera_leases_granted_total",
                                   "Leases granted to workers since the coordinator started")
                         .Add({})),
      jobs(GaugeFamily(registry, "tessera_jobs", "Jobs known to the coordinator, by state")),
      workers(GaugeFamily(registry, "tessera_workers",
                          "Workers known since the coordinator started, by state")),
      worker_samples_per_second(
          GaugeFamily(registry, "tessera_worker_samples_per_second",
                      "Camera samples per second the worker rendered over its last heartbeats"),
          "worker", false),
      worker_rays_per_second(
          GaugeFamily(registry, "tessera_worker_rays_per_second",
                      "Rays per second the worker traced over its last heartbeats"),
          "worker", false),
      worker_tasks_leased(
          GaugeFamily(registry, "tessera_worker_tasks_leased", "Leases the worker holds now"),
          "worker", false),
      worker_last_seen(GaugeFamily(registry, "tessera_worker_last_seen_seconds",
                                   "Seconds since the coordinator last heard from the worker"),
                       "worker", false),
      blob_bytes(GaugeFamily(registry, "tessera_blob_store_bytes",
                             "Bytes of the blobs in the coordinator's blob store")
                     .Add({})),
      blob_count(
          GaugeFamily(registry, "tessera_blob_store_blobs", "Blobs in the coordinator's blob store")
              .Add({})),
      frame_assembly(BuildHistogram()
                         .Name("tessera_frame_assembly_seconds")
                         .Help("Time to assemble a frame and write its EXR and preview")
                         .Register(registry)
                         .Add({}, kWorkBuckets)),
      stage_merge(BuildHistogram()
                      .Name("tessera_stage_merge_seconds")
                      .Help("Time to merge an artifact stage of a frame (photon map, irradiance "
                            "cache) and store the artifact, by stage")
                      .Register(registry)),
      farm_problem(GaugeFamily(registry, "tessera_farm_problem",
                               "1 while the farm cannot progress (out of disk space), else 0")
                       .Add({})),
      queued_tasks(GaugeFamily(registry, "tessera_queued_tasks",
                               "Unfinished tasks of all unfinished jobs (what the coordinator's "
                               "max queued tasks limit caps)")
                       .Add({})),
      refresh_errors(CounterFamily(registry, "tessera_metrics_refresh_errors_total",
                                   "Parts of a scrape that could not be read from the "
                                   "coordinator, by part")) {
    for (const char* state : kJobStates) jobs.Add({{"state", state}});
    for (const char* state : kWorkerStates) workers.Add({{"state", state}});
    coordinator.FrameWork().SetTimingObserver(
        [this](const FrameWorkTiming& timing) { OnFrameWork(timing); });
}

FarmMetrics::Impl::~Impl() { coordinator.FrameWork().SetTimingObserver({}); }

void FarmMetrics::Impl::OnFrameWork(const FrameWorkTiming& timing) {
    if (timing.kind == FrameWorkTiming::kFrameAssembly)
        frame_assembly.Observe(timing.seconds);
    else
        stage_merge.Add({{"stage", timing.stage}}, kWorkBuckets).Observe(timing.seconds);
}

void FarmMetrics::Impl::Refresh() {
    RefreshPart("tasks", [this] { RefreshTasks(); });  // before the counters: the stages seen
    RefreshPart("counters", [this] { RefreshCounters(); });
    RefreshPart("jobs", [this] { RefreshJobs(); });
    RefreshPart("workers", [this] { RefreshWorkers(); });
    RefreshPart("farm", [this] { RefreshFarm(); });
}

void FarmMetrics::Impl::RefreshPart(const char* part, const std::function<void()>& refresh) {
    try {
        refresh();
    } catch (const std::exception& e) {
        spdlog::warn("metrics: cannot read the {}: {}", part, e.what());
        refresh_errors.Add({{"part", part}}).Increment();
    }
}

void FarmMetrics::Impl::RefreshTasks() {
    for (auto& [key, gauge] : task_gauges) gauge->Set(0);
    for (const StageTaskCounts& s : coordinator.GetScheduler().TaskCountsByStage()) {
        const int64_t counts[] = {s.waiting, s.pending, s.leased, s.done};
        for (size_t i = 0; i < std::size(kTaskStates); ++i) {
            Gauge*& gauge = task_gauges[{s.stage, kTaskStates[i]}];
            if (!gauge) gauge = &tasks.Add({{"stage", s.stage}, {"state", kTaskStates[i]}});
            gauge->Set(static_cast<double>(counts[i]));
        }
    }
}

void FarmMetrics::Impl::RefreshCounters() {
    const SchedulerCounters counters = coordinator.GetScheduler().Counters();
    AdvanceTo(leases_granted, static_cast<double>(counters.leases_granted));
    const std::pair<Family<Counter>*, const std::map<std::string, int64_t>*> by_stage[] = {
        {&tasks_completed, &counters.completed_by_stage},
        {&tasks_failed, &counters.failed_by_stage},
        {&lease_expiries, &counters.expired_by_stage}};
    for (const auto& [family, totals] : by_stage) {
        // Every stage seen gets its series from 0, so that the first failure or expiry
        // shows in rate() and increase() (they see nothing before a series' first sample).
        for (const auto& [key, gauge] : task_gauges) family->Add({{"stage", key.first}});
        for (const auto& [stage, total] : *totals)
            AdvanceTo(family->Add({{"stage", stage}}), static_cast<double>(total));
    }
}

void FarmMetrics::Impl::RefreshJobs() {
    std::map<std::string, int64_t> by_state;
    for (const char* state : kJobStates) by_state[state] = 0;
    for (const auto& [state, n] : coordinator.GetScheduler().JobCountsByState()) {
        std::string label = JobStateName(state);
        for (char& c : label) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        by_state[label] += n;
    }
    for (const auto& [state, n] : by_state) jobs.Add({{"state", state}}).Set(n);
}

void FarmMetrics::Impl::RefreshWorkers() {
    const int64_t now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
    std::map<std::string, int> by_state;
    for (const char* state : kWorkerStates) by_state[state] = 0;
    KeyedGauges* per_worker[] = {&worker_samples_per_second, &worker_rays_per_second,
                                 &worker_tasks_leased, &worker_last_seen};
    for (KeyedGauges* g : per_worker) g->Begin();
    for (const v1::WorkerStatus& w : coordinator.ListWorkers()) {
        ++by_state[w.state()];
        worker_samples_per_second.Set(w.name(), w.samples_per_second());
        worker_rays_per_second.Set(w.name(), w.rays_per_second());
        worker_tasks_leased.Set(w.name(), w.tasks_leased());
        worker_last_seen.Set(w.name(),
                             std::max<int64_t>(0, now_ms - w.last_seen_unix_ms()) / 1000.0);
    }
    for (KeyedGauges* g : per_worker) g->End();
    for (const auto& [state, n] : by_state) workers.Add({{"state", state}}).Set(n);
}

void FarmMetrics::Impl::RefreshFarm() {
    const BlobStore::Usage usage = coordinator.Blobs().CurrentUsage();
    blob_bytes.Set(static_cast<double>(usage.bytes));
    blob_count.Set(static_cast<double>(usage.blobs));
    farm_problem.Set(coordinator.DiskSpace().OutOfSpace() ? 1 : 0);
    queued_tasks.Set(static_cast<double>(coordinator.QueuedTasks()));
}

FarmMetrics::FarmMetrics(Coordinator& coordinator) : impl_(std::make_unique<Impl>(coordinator)) {}

FarmMetrics::~FarmMetrics() = default;

std::string FarmMetrics::Scrape() {
    std::lock_guard lock(impl_->mu);
    impl_->Refresh();
    return prometheus::TextSerializer().Serialize(impl_->registry.Collect());
}

}  // namespace tessera
