// Crash tolerance under chaos: a real coordinator and four real workers render a job of
// hundreds of small tiles while a driver kills (SIGKILL) random workers, restarting each
// at once, and kills and restarts the coordinator on the same state and port. The
// frames must still equal the local render bit for bit, and no task may have been
// completed twice: a completion, once recorded, is final (the tasks table counts every
// recorded completion of a task; the coordinator logs each one after its commit).
//
// The kills follow the job's progress (tasks done), not the clock, so that a slow or
// loaded machine sees the same chaos as a fast one. The random choices come from a seed
// that is printed; TESSERA_CHAOS_SEED replays one.

#include <sqlite3.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include "farm_harness.h"

namespace tessera {
namespace {

using namespace farm_testing;

// Two frames of 16 x 16 tiles: 512 tasks, each a few milliseconds of rendering, so that
// the farm's own work (leases, uploads, commits, restarts) is what the test exercises.
const std::vector<std::string> kManyTiles = {"--width", "128", "--height",    "128",
                                             "--spp",   "2",   "--tile-size", "8"};
constexpr int kFrames = 2;
constexpr int kWorkers = 4;
constexpr int kWorkerKills = 32;
constexpr int kCoordinatorRestarts = 3;
// Short leases: a killed worker's task runs elsewhere soon. Results of a worker that
// lost its lease to a slow heartbeat are refused, which the test also exercises.
constexpr int kLeaseMs = 1500;

// Recorded completions per task of a job, read from the coordinator's database.
struct Completions {
    int tasks = 0;
    int64_t total = 0;
    int never = 0;  // tasks not completed
    int twice = 0;  // tasks completed more than once
    std::string error;
};

Completions ReadCompletions(const fs::path& db_path, int64_t job_id) {
    Completions c;
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
        c.error = "cannot open " + db_path.string() + ": " + sqlite3_errmsg(db);
        sqlite3_close(db);
        return c;
    }
    sqlite3_stmt* stmt = nullptr;
    const char* sql = "SELECT completions FROM tasks WHERE job_id = ?1";
    if (sqlite3_prepare_v2(db, sql, -1, &stmt, nullptr) != SQLITE_OK) {
        c.error = std::string("cannot read the tasks: ") + sqlite3_errmsg(db);
    } else {
        sqlite3_bind_int64(stmt, 1, job_id);
        int rc = SQLITE_OK;
        while ((rc = sqlite3_step(stmt)) == SQLITE_ROW) {
            const int64_t n = sqlite3_column_int64(stmt, 0);
            ++c.tasks;
            c.total += n;
            c.never += n == 0;
            c.twice += n > 1;
        }
        if (rc != SQLITE_DONE) c.error = std::string("reading the tasks: ") + sqlite3_errmsg(db);
    }
    sqlite3_finalize(stmt);
    sqlite3_close(db);
    return c;
}

// The coordinators log each lease and completion at debug level.
const std::vector<std::string> kDebugLog = {"--log-level", "debug"};

// Completions per task id as the coordinators' logs (one per start) report them.
std::map<int64_t, int> LoggedCompletions(const fs::path& dir, const std::string& state) {
    static const std::regex kCompleted(R"(lease \d+: task (\d+) \(.*\) completed by worker)");
    std::map<int64_t, int> per_task;
    for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
        const std::string name = e.path().filename().string();
        if (name.rfind(state + "-", 0) != 0 || e.path().extension() != ".log") continue;
        std::istringstream lines(ReadFile(e.path()));
        std::smatch m;
        for (std::string line; std::getline(lines, line);)
            if (std::regex_search(line, m, kCompleted)) ++per_task[std::stoll(m[1].str())];
    }
    return per_task;
}

// How many occurrences of `text` the file holds from byte `from` on.
int CountFrom(const fs::path& path, size_t from, const std::string& text) {
    const std::string all = ReadFile(path);
    int count = 0;
    for (size_t at = std::min(from, all.size()); (at = all.find(text, at)) != std::string::npos;
         at += text.size())
        ++count;
    return count;
}

class ChaosTest : public FarmHarness {
  protected:
    // A worker process and where its run's lines start in its log (one log per name).
    struct Slot {
        Process* process = nullptr;
        std::string name;
        size_t log_from = 0;
    };
    fs::path LogOf(const Slot& slot) const { return dir_ / (slot.name + ".log"); }
    void Launch(Slot& slot, int port) {
        std::error_code ec;
        const uintmax_t size = fs::file_size(LogOf(slot), ec);
        slot.log_from = ec ? 0 : static_cast<size_t>(size);
        slot.process = &StartWorker(port, slot.name);
    }
    // The worker's log says it holds a task now: more leased than finished since it started.
    bool Busy(const Slot& slot) const {
        const fs::path log = LogOf(slot);
        return CountFrom(log, slot.log_from, "] leased ") >
               CountFrom(log, slot.log_from, "] completed ") +
                   CountFrom(log, slot.log_from, ": dropped ");
    }
};

TEST_F(ChaosTest, RandomKillsOfWorkersAndCoordinatorLeaveTheImagesUnchanged) {
    uint32_t seed = std::random_device{}();
    if (const char* s = std::getenv("TESSERA_CHAOS_SEED")) seed = std::stoul(s);
    std::printf("chaos seed %u (TESSERA_CHAOS_SEED=%u replays it)\n", seed, seed);
    std::mt19937 rng(seed);

    Process* coordinator = nullptr;
    const int port = StartCoordinator("state", 0, kLeaseMs, &coordinator, kDebugLog);
    ASSERT_GT(port, 0);
    std::vector<Slot> workers(kWorkers);
    for (int i = 0; i < kWorkers; ++i) {
        workers[i].name = "w" + std::to_string(i + 1);
        Launch(workers[i], port);
    }
    Stubs s(port);
    const std::string job_id = SubmitCornell(s, kManyTiles, 0, kFrames - 1);
    ASSERT_FALSE(job_id.empty());
    v1::JobStatus status;
    ASSERT_TRUE(PollJob(
        s, job_id, [](const v1::JobStatus&) { return true; }, 120s, &status));
    const int total = status.tasks_total();
    ASSERT_GE(total, 500);

    // The chaos plan: at which count of tasks done each kill comes. Worker kills are
    // spread at random over the job; coordinator restarts near each quarter.
    struct Event {
        int at_done;
        bool coordinator;
    };
    std::vector<Event> plan;
    std::uniform_real_distribution<double> spread(0.03, 0.92), jitter(-0.05, 0.05);
    for (int i = 0; i < kWorkerKills; ++i)
        plan.push_back({static_cast<int>(spread(rng) * total), false});
    for (int i = 1; i <= kCoordinatorRestarts; ++i)
        plan.push_back({static_cast<int>((0.25 * i + jitter(rng)) * total), true});
    std::sort(plan.begin(), plan.end(),
              [](const Event& a, const Event& b) { return a.at_done < b.at_done; });

    int worker_kills = 0, kills_mid_task = 0, coordinator_restarts = 0;
    size_t next = 0;
    auto deadline = Clock::now() + 360s;
    bool finished = false;
    while (!finished && Clock::now() < deadline) {
        v1::JobStatus now;
        if (!PollJob(
                s, job_id, [](const v1::JobStatus&) { return true; }, 60s, &now))
            continue;
        status = now;
        finished = now.state() != v1::JOB_STATE_RUNNING && now.state() != v1::JOB_STATE_QUEUED;
        while (!finished && next < plan.size() && plan[next].at_done <= now.tasks_done()) {
            if (plan[next++].coordinator) {
                coordinator->Kill(SIGKILL);
                ++coordinator_restarts;
                // The same state and port: the workers find it again by themselves.
                ASSERT_EQ(StartCoordinator("state", port, kLeaseMs, &coordinator, kDebugLog), port);
                // The events left are judged against the restarted coordinator's count.
                break;
            }
            // A random worker among those at work on a task (any, if none is).
            std::vector<int> busy, candidates;
            for (int i = 0; i < kWorkers; ++i)
                if (Busy(workers[i])) busy.push_back(i);
            candidates = busy;
            if (candidates.empty())
                for (int i = 0; i < kWorkers; ++i) candidates.push_back(i);
            const int w =
                candidates[std::uniform_int_distribution<size_t>(0, candidates.size() - 1)(rng)];
            workers[w].process->Kill(SIGKILL);
            ++worker_kills;
            kills_mid_task += !busy.empty();
            Launch(workers[w], port);
        }
        std::this_thread::sleep_for(20ms);
    }
    ASSERT_TRUE(finished) << "the job did not finish; last: " << status.ShortDebugString();
    ASSERT_EQ(status.state(), v1::JOB_STATE_DONE) << status.ShortDebugString();
    EXPECT_EQ(status.tasks_done(), total);
    EXPECT_EQ(worker_kills, kWorkerKills) << "the job ended before the chaos did";
    EXPECT_EQ(coordinator_restarts, kCoordinatorRestarts) << "the job ended before the chaos did";

    // No task completed twice: in the database (every recorded completion counts) and in
    // the logs of every coordinator that ran (each logs a completion after its commit).
    const Completions db = ReadCompletions(dir_ / "state" / "tessera.db",
                                           std::stoll(job_id.substr(job_id.find('-') + 1)));
    EXPECT_TRUE(db.error.empty()) << db.error;
    EXPECT_EQ(db.tasks, total);
    EXPECT_EQ(db.never, 0) << "tasks never completed in a finished job";
    EXPECT_EQ(db.twice, 0) << "tasks completed twice";
    EXPECT_EQ(db.total, total);
    const std::map<int64_t, int> logged = LoggedCompletions(dir_, "state");
    int logged_twice = 0;
    for (const auto& [task, count] : logged)
        if (count > 1) {
            ++logged_twice;
            ADD_FAILURE() << "task " << task << " was logged as completed " << count << " times";
        }
    std::printf(
        "tiles %d in %d frames; worker kills %d (%d with a task in flight), coordinator "
        "restarts %d; leases granted %lld; completions recorded %lld, tasks completed twice "
        "%d (database), %d (logs, %zu tasks logged)\n",
        total, kFrames, worker_kills, kills_mid_task, coordinator_restarts,
        static_cast<long long>(status.leases_granted()), static_cast<long long>(db.total), db.twice,
        logged_twice, logged.size());

    for (int frame = 0; frame < kFrames; ++frame) {
        SCOPED_TRACE("frame " + std::to_string(frame));
        ExpectSameImage(RenderLocal(kManyTiles, frame), Download(s, job_id, frame));
    }
}

}  // namespace
}  // namespace tessera
