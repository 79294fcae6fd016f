// The farm as its users run it: a real coordinator and real workers as processes on
// 127.0.0.1, the `tessera` command, and the gRPC API spoken directly where a test must
// play a misbehaving client or worker. Every farm image must equal the local render bit
// for bit, whatever crashes on the way.
//
// Each test has its own folders and ports (port 0, read back from --port-file); every
// wait is a poll with a deadline; every process is killed with its group in TearDown.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "command_line.h"
#include "farm_harness.h"
#include "plan/frame_renderer.h"
#include "plan/render_plan.h"
#include "scene/scene_loader.h"
#include "scene_files.h"
#include "sha256.h"

namespace tessera {
namespace {

using namespace farm_testing;

// Small enough for two cores, with several tiles so that several workers share a frame.
const std::vector<std::string> kSmall = {"--width", "64", "--height",    "64",
                                         "--spp",   "4",  "--tile-size", "16"};
// Enough work (64 tiles) that a crash can happen in the middle of the job.
const std::vector<std::string> kMedium = {"--width", "128", "--height",    "128",
                                          "--spp",   "24",  "--tile-size", "16"};
// Multi-stage plans, small: photon mapping with its final gather behind an irradiance
// cache (photons 4, irradiance-1 16, irradiance-2 16, render 16 tasks), and irradiance
// caching alone (the photon options are unused there).
const std::vector<std::string> kStagedSmall = {"--width",
                                               "64",
                                               "--height",
                                               "64",
                                               "--spp",
                                               "4",
                                               "--tile-size",
                                               "16",
                                               "--photons",
                                               "20000",
                                               "--caustic-photons",
                                               "5000",
                                               "--photon-batches",
                                               "4",
                                               "--ic-passes",
                                               "2",
                                               "--ic-samples",
                                               "64"};
const std::vector<std::string> kPhotonIc = {"--integrator", "photon", "--irradiance-cache"};
const std::vector<std::string> kIrradianceCache = {"--integrator", "irradiance-cache"};
// Longer stages (16 tasks of ~50 ms each) for crashes in the middle of one.
const std::vector<std::string> kStagedMedium = {"--width",
                                                "128",
                                                "--height",
                                                "128",
                                                "--spp",
                                                "8",
                                                "--tile-size",
                                                "32",
                                                "--photons",
                                                "20000",
                                                "--caustic-photons",
                                                "5000",
                                                "--photon-batches",
                                                "4",
                                                "--ic-passes",
                                                "2",
                                                "--ic-samples",
                                                "256"};

class FarmTest : public FarmHarness {};

// submit, watch, status and fetch as a user types them, against three workers.
TEST_F(FarmTest, ThreeWorkersMatchTheLocalRender) {
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    for (int i = 1; i <= 3; ++i) StartWorker(port, "w" + std::to_string(i));
    std::string address = "127.0.0.1:" + std::to_string(port);

    // Enough tiles that all three workers get some.
    CliResult submit =
        Cli(Concat({"submit", kCornell, "--coordinator", address, "--name", "box"}, kMedium));
    ASSERT_EQ(submit.code, 0) << submit.err;
    std::string job_id = Trim(submit.out);
    ASSERT_FALSE(job_id.empty());
    EXPECT_EQ(job_id.find('\n'), std::string::npos) << "stdout holds only the id: " << submit.out;

    CliResult watch = Cli({"watch", job_id, "--coordinator", address});
    EXPECT_EQ(watch.code, 0) << watch.err;

    CliResult status = Cli({"status", job_id, "--coordinator", address});
    EXPECT_EQ(status.code, 0) << status.err;
    EXPECT_NE(status.out.find("DONE"), std::string::npos) << status.out;
    CliResult table = Cli({"status", "--coordinator", address});
    EXPECT_NE(table.out.find(job_id), std::string::npos) << table.out;

    fs::path out = dir_ / "frames";
    CliResult fetch = Cli({"fetch", job_id, "-o", out.string(), "--coordinator", address});
    ASSERT_EQ(fetch.code, 0) << fetch.err;
    ExpectSameImage(RenderLocal(kMedium), out / "box.0000.exr");
}

TEST_F(FarmTest, OneWorkerMatchesTheLocalRender) {
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    StartWorker(port, "only", 2);
    std::string address = "127.0.0.1:" + std::to_string(port);
    CliResult submit =
        Cli(Concat({"submit", kCornell, "--coordinator", address, "--watch"}, kSmall));
    ASSERT_EQ(submit.code, 0) << submit.err;
    std::string job_id = Trim(submit.out);
    fs::path out = dir_ / "frames";
    CliResult fetch =
        Cli({"fetch", job_id, "-o", out.string(), "--preview", "--coordinator", address});
    ASSERT_EQ(fetch.code, 0) << fetch.err;
    EXPECT_TRUE(fs::exists(out / "cornell-box.0000.png"));
    ExpectSameImage(RenderLocal(kSmall), out / "cornell-box.0000.exr");
}

// An environment map's strata and a measured BRDF's factorisation are made once per job,
// by the coordinator while it plans it: the worker installs them from the coordinator's
// blobs and makes none of its own, and the image is the local render's, bit for bit.
TEST_F(FarmTest, PrecomputedTablesAreShippedToWorkers) {
    const fs::path scene_dir = dir_ / "tables-scene";
    fs::create_directories(scene_dir);
    test::WriteSunSkyGlossyScene(scene_dir,
                                 R"({"width": 32, "height": 24, "spp": 4, "tile_size": 16})");
    const std::string scene = (scene_dir / "scene.json").string();
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    StartWorker(port, "only", 2);
    const std::string address = "127.0.0.1:" + std::to_string(port);
    CliResult submit =
        Cli({"submit", scene, "--coordinator", address, "--name", "tables", "--watch"});
    ASSERT_EQ(submit.code, 0) << submit.err;
    const std::string job_id = Trim(submit.out);
    const fs::path out = dir_ / "frames";
    CliResult fetch = Cli({"fetch", job_id, "-o", out.string(), "--coordinator", address});
    ASSERT_EQ(fetch.code, 0) << fetch.err;
    const fs::path local = dir_ / "tables-local.exr";
    CliResult render = Cli({"render", scene, "-q", "-o", local.string()});
    ASSERT_EQ(render.code, 0) << render.err;
    ExpectSameImage(local, out / "tables.0000.exr");
    const std::string log = ReadFile(dir_ / "only.log");
    EXPECT_NE(log.find("2 precomputed tables, 0 tables made here"), std::string::npos) << log;
}

// `watch` of a job no worker takes: on a terminal (script(1) gives it one) the bar says
// "waiting for workers" and keeps being redrawn, its elapsed time running, although no
// event arrives.
TEST_F(FarmTest, WatchOfAnIdleFarmSaysWaitingForWorkersAndTicks) {
    const int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    const std::string address = "127.0.0.1:" + std::to_string(port);
    CliResult submit = Cli(Concat({"submit", kCornell, "--coordinator", address}, kSmall));
    ASSERT_EQ(submit.code, 0) << submit.err;
    const std::string job_id = Trim(submit.out);
    const fs::path typescript = dir_ / "watch.typescript";
    const std::string command = "stty cols 160 rows 20; timeout 3.5 " + std::string(TESSERA_CLI) +
                                " watch " + job_id + " --coordinator " + address;
    const std::string script =
        "script -qfc '" + command + "' " + typescript.string() + " > /dev/null 2>&1 < /dev/null";
    std::system(script.c_str());  // ended by timeout
    const std::string text = ReadFile(typescript);
    std::set<std::string> elapsed;
    size_t at = 0;
    int redraws = 0;
    while ((at = text.find("waiting for workers", at)) != std::string::npos) {
        ++redraws;
        const size_t e = text.find("elapsed ", at);
        if (e != std::string::npos)
            elapsed.insert(text.substr(e, text.find_first_of("\r\n", e) - e));
        ++at;
    }
    EXPECT_GE(redraws, 2) << text;
    EXPECT_GE(elapsed.size(), 2u) << "the line froze: " << text;
}

// Light tracing on the farm: its render stage is made of splat tasks (here 16 bands of
// 1024 light paths, each a whole-frame buffer), summed in task order as the local runner
// sums them, whichever of the two workers ran which task.
TEST_F(FarmTest, LightTracingMatchesTheLocalRender) {
    const std::vector<std::string> light =
        Concat(kSmall, {"--integrator", "light", "--light-paths-per-task", "1024"});
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    StartWorker(port, "w1", 1);
    StartWorker(port, "w2", 1);
    Stubs s(port);
    const std::string job = SubmitCornell(s, light);
    v1::JobStatus status;
    ASSERT_TRUE(WaitDone(s, job, &status));
    EXPECT_EQ(status.tasks_total(), 16);
    ExpectSameImage(RenderLocal(light), Download(s, job, 0));
}

// Bidirectional path tracing on the farm: a light-path stage of splat tasks (the t = 1
// strategies) and the render stage's tiles (every other strategy) trace the same light
// subpaths, and the frame is their sum, as the local runner makes it.
TEST_F(FarmTest, BdptMatchesTheLocalRender) {
    const std::vector<std::string> bdpt =
        Concat(kSmall, {"--integrator", "bdpt", "--light-paths-per-task", "2048"});
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    StartWorker(port, "w1", 1);
    StartWorker(port, "w2", 1);
    Stubs s(port);
    const std::string job = SubmitCornell(s, bdpt);
    v1::JobStatus status;
    ASSERT_TRUE(WaitDone(s, job, &status));
    ExpectSameImage(RenderLocal(bdpt), Download(s, job, 0));
}

// Metropolis light transport on the farm: the bootstrap stage's batches merge (on the
// coordinator) into b and the chains' starts, which every chain task reads; the chains'
// splat buffers sum to the local render's image, bit for bit.
TEST_F(FarmTest, MltMatchesTheLocalRender) {
    const std::vector<std::string> mlt =
        Concat(kSmall, {"--integrator", "mlt", "--max-depth", "5", "--mlt-bootstrap", "4000",
                        "--mlt-chains", "48"});
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    StartWorker(port, "w1", 1);
    StartWorker(port, "w2", 1);
    Stubs s(port);
    const std::string job = SubmitCornell(s, mlt);
    v1::JobStatus status;
    ASSERT_TRUE(WaitDone(s, job, &status));
    // 32 bootstrap batches and 32 tasks of chains (48 chains, 2 to a task: 24).
    EXPECT_EQ(status.tasks_total(), 32 + 24);
    ExpectSameImage(RenderLocal(mlt), Download(s, job, 0));
}

// The README's command: a whole farm on this machine, two frames, with its dashboard.
TEST_F(FarmTest, FarmCommandMatchesTheLocalRender) {
    fs::path out = dir_ / "frames";
    CliResult farm = Cli(Concat({"farm", kCornell, "--workers", "2", "--threads-per-worker", "1",
                                 "--frames", "0-1", "-o", out.string(), "--keep-state",
                                 (dir_ / "farm-state").string(), "--dashboard", "0"},
                                kSmall),
                         240s);
    ASSERT_EQ(farm.code, 0) << farm.err;
    EXPECT_NE(farm.err.find("dashboard: http://127.0.0.1:"), std::string::npos) << farm.err;
    EXPECT_TRUE(fs::exists(dir_ / "farm-state" / "http-port"));
    ExpectSameImage(RenderLocal(kSmall, 0), out / "cornell-box.0000.exr");
    ExpectSameImage(RenderLocal(kSmall, 1), out / "cornell-box.0001.exr");
    EXPECT_TRUE(fs::exists(out / "cornell-box.0001.png"));
    // The coordinator and the workers went with it.
    EXPECT_EQ(ProcessesMentioning((dir_ / "farm-state").string()), 0);
}

// `tessera farm` stopped by Ctrl-C, or killed outright, leaves no process behind.
TEST_F(FarmTest, FarmCommandLeavesNothingRunning) {
    for (int sig : {SIGINT, SIGKILL}) {
        SCOPED_TRACE(strsignal(sig));
        fs::path state = dir_ / ("state-" + std::to_string(sig));
        Process& farm =
            Start({TESSERA_CLI, "farm", kCornell, "--workers", "2", "--threads-per-worker", "1",
                   "--width", "128", "--height", "128", "--spp", "256", "--tile-size", "16", "-o",
                   (dir_ / "frames").string(), "--keep-state", state.string()},
                  "farm-" + std::to_string(sig));
        // Wait until it renders: a coordinator that serves and a task done.
        auto deadline = Clock::now() + 180s;
        bool rendering = false;
        while (!rendering && farm.Running() && Clock::now() < deadline) {
            std::this_thread::sleep_for(50ms);
            int port = 0;
            if (!(std::istringstream(ReadFile(state / "port")) >> port) || port <= 0) continue;
            Stubs s(port);
            Ctx ctx(2s);
            v1::ListJobsResponse jobs;
            rendering = s.farm->ListJobs(&ctx, v1::ListJobsRequest(), &jobs).ok() &&
                        jobs.jobs_size() == 1 && jobs.jobs(0).tasks_done() >= 1;
        }
        ASSERT_TRUE(rendering) << ReadFile(dir_ / ("farm-" + std::to_string(sig) + ".log"));
        ASSERT_EQ(ProcessesMentioning(state.string()), 4) << "tessera, a coordinator, two workers";
        farm.Kill(sig);
        if (sig == SIGINT) {
            EXPECT_EQ(farm.Wait(120s), 130);
        }
        deadline = Clock::now() + 120s;
        while (ProcessesMentioning(state.string()) > 0 && Clock::now() < deadline)
            std::this_thread::sleep_for(50ms);
        EXPECT_EQ(ProcessesMentioning(state.string()), 0) << "children outlived `tessera farm`";
    }
}

TEST_F(FarmTest, KilledWorkerDoesNotStopTheJob) {
    int port = StartCoordinator("state", 0, 1500);
    ASSERT_GT(port, 0);
    Process& doomed = StartWorker(port, "doomed");
    StartWorker(port, "survivor");
    Stubs s(port);
    std::string job_id = SubmitCornell(s, kMedium);
    v1::JobStatus status;
    // Both workers (one thread each) at work: two leases out, so the doomed one holds one
    // (unless it finishes its tile in the moment before the kill).
    ASSERT_TRUE(PollJob(
        s, job_id,
        [](const v1::JobStatus& j) {
            return j.tasks_done() >= 1 && j.leases_granted() - j.tasks_done() >= 2;
        },
        180s, &status))
        << status.ShortDebugString();
    ASSERT_LT(status.tasks_done(), status.tasks_total() - 2) << "no middle to kill the worker in";
    doomed.Kill(SIGKILL);
    int done_at_kill = status.tasks_done();
    ASSERT_TRUE(WaitDone(s, job_id, &status));
    std::printf("tasks %d, leases granted %lld (killed at %d done)\n", status.tasks_total(),
                static_cast<long long>(status.leases_granted()), done_at_kill);
    EXPECT_GE(status.leases_granted(), status.tasks_total());
    ExpectSameImage(RenderLocal(kMedium), Download(s, job_id, 0));
}

TEST_F(FarmTest, CoordinatorRestartKeepsFinishedTiles) {
    // Longer tiles than kMedium: `tessera watch` must be following before the kill.
    const std::vector<std::string> settings = {"--width", "128", "--height",    "128",
                                               "--spp",   "64",  "--tile-size", "16"};
    // Leases long enough that a worker slowed down by a loaded machine keeps them: the
    // count of leases below is then exact however slow the run.
    constexpr int kLeaseMs = 5000;
    Process* coordinator = nullptr;
    int port = StartCoordinator("state", 0, kLeaseMs, &coordinator);
    ASSERT_GT(port, 0);
    constexpr int kWorkers = 2;
    for (int i = 1; i <= kWorkers; ++i) StartWorker(port, "w" + std::to_string(i));
    std::string job_id;
    v1::JobStatus before;
    Process* watch = nullptr;
    {
        Stubs s(port);
        job_id = SubmitCornell(s, settings);
        // `tessera watch` rides out the restart.
        watch = &Start(
            {TESSERA_CLI, "watch", job_id, "--coordinator", "127.0.0.1:" + std::to_string(port)},
            "watch");
        // Some tiles done, both workers busy, and the watch following.
        ASSERT_TRUE(PollJob(
            s, job_id,
            [&](const v1::JobStatus& j) {
                return j.tasks_done() >= 8 && j.leases_granted() - j.tasks_done() >= kWorkers &&
                       ReadFile(dir_ / "watch.log").find(job_id) != std::string::npos;
            },
            180s, &before))
            << before.ShortDebugString() << "\nwatch: " << ReadFile(dir_ / "watch.log");
    }
    ASSERT_LT(before.tasks_done(), before.tasks_total() - 4) << "no middle to kill it in";
    coordinator->Kill(SIGKILL);
    // The same state, the same port: the workers find it again by themselves.
    ASSERT_EQ(StartCoordinator("state", port, kLeaseMs), port);
    Stubs s(port);
    v1::JobStatus after;
    ASSERT_TRUE(PollJob(
        s, job_id, [](const v1::JobStatus&) { return true; }, 120s, &after));
    EXPECT_GE(after.tasks_done(), before.tasks_done()) << "finished tiles were lost";
    ASSERT_TRUE(WaitDone(s, job_id, &after));
    std::printf("tasks %d, done before the kill >= %d, leases granted %lld\n", after.tasks_total(),
                before.tasks_done(), static_cast<long long>(after.leases_granted()));
    // Only the tasks in flight at the kill may be leased again (one per worker thread),
    // and perhaps once more each if the restart outlived a lease.
    EXPECT_LE(after.leases_granted(), after.tasks_total() + 2 * kWorkers);
    EXPECT_EQ(watch->Wait(120s), 0) << ReadFile(dir_ / "watch.log");
    ExpectSameImage(RenderLocal(settings), Download(s, job_id, 0));
}

// A worker whose lease expired must not have its result accepted once the task was
// given to another: fencing by lease id.
TEST_F(FarmTest, StaleResultIsRejected) {
    int port = StartCoordinator("state", 0, 1000);
    ASSERT_GT(port, 0);
    Stubs s(port);
    const std::vector<std::string> one_tile = {"--width", "16", "--height",    "16",
                                               "--spp",   "4",  "--tile-size", "16"};
    std::string job_id = SubmitCornell(s, one_tile);

    auto register_worker = [&](const std::string& name) {
        Ctx ctx;
        v1::RegisterRequest req;
        req.set_name(name);
        req.set_threads(1);
        v1::RegisterResponse resp;
        grpc::Status st = s.workers->Register(&ctx, req, &resp);
        EXPECT_TRUE(st.ok()) << StatusText(st);
        return resp.worker_id();
    };
    auto lease = [&](const std::string& worker_id) {
        auto deadline = Clock::now() + 120s;
        while (Clock::now() < deadline) {
            Ctx ctx;
            v1::LeaseTaskRequest req;
            req.set_worker_id(worker_id);
            req.set_wait_ms(1000);
            v1::LeaseTaskResponse resp;
            grpc::Status st = s.workers->LeaseTask(&ctx, req, &resp);
            EXPECT_TRUE(st.ok()) << StatusText(st);
            if (!st.ok() || resp.has_task()) return resp.task();
        }
        ADD_FAILURE() << "no task leased within 120 s";
        return v1::Task();
    };
    auto complete = [&](const std::string& worker_id, const v1::Task& task, const std::string& hash,
                        const std::string& inline_result = "") {
        Ctx ctx;
        v1::CompleteTaskRequest req;
        req.set_worker_id(worker_id);
        req.set_task_id(task.task_id());
        req.set_lease_id(task.lease_id());
        req.set_lease_token(task.lease_token());
        req.set_result_hash(hash);
        req.set_result(inline_result);
        v1::CompleteTaskResponse resp;
        return s.workers->CompleteTask(&ctx, req, &resp);
    };

    std::string first = register_worker("slow"), second = register_worker("fast");
    v1::Task stale = lease(first);
    ASSERT_GT(stale.task_id(), 0);
    // `slow` stays silent; the lease runs out and `fast` gets the task.
    v1::Task current = lease(second);
    ASSERT_EQ(current.task_id(), stale.task_id());
    EXPECT_NE(current.lease_id(), stale.lease_id());
    EXPECT_EQ(current.attempt(), stale.attempt() + 1);
    // `fast` keeps its lease alive as a worker does, however long the steps below take.
    std::atomic<bool> finished{false};
    std::thread heartbeats([&] {
        while (!finished) {
            Ctx ctx(5s);
            v1::HeartbeatRequest req;
            req.set_worker_id(second);
            req.set_task_id(current.task_id());
            req.set_lease_id(current.lease_id());
            req.set_lease_token(current.lease_token());
            v1::HeartbeatResponse resp;
            s.workers->Heartbeat(&ctx, req, &resp);
            std::this_thread::sleep_for(100ms);
        }
    });
    struct StopHeartbeats {
        std::atomic<bool>& finished;
        std::thread& thread;
        ~StopHeartbeats() {
            finished = true;
            thread.join();
        }
    } stop_heartbeats{finished, heartbeats};

    // The real result of the tile, rendered here as a worker would.
    RenderOverrides overrides = FromProto(current.spec().options());
    LoadedScene loaded = LoadSceneFile(kCornell, overrides);
    loaded.settings.frame = current.frame();
    FrameRenderer renderer(*loaded.scene, loaded.settings);
    ScratchBuffer arena;
    std::string result = EncodeTileResult(ExecuteTileTask(renderer, current.task_index(), arena));

    // Sent inline by the stale holder: refused, and not stored.
    grpc::Status st = complete(first, stale, "", result);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << StatusText(st);
    {
        Ctx ctx;
        v1::FindMissingBlobsRequest req;
        req.add_hashes(Sha256Hex(result));
        v1::FindMissingBlobsResponse resp;
        ASSERT_TRUE(s.blobs->FindMissingBlobs(&ctx, req, &resp).ok());
        EXPECT_EQ(resp.missing_size(), 1) << "a stale inline result was stored";
    }
    std::string hash = UploadBlob(*s.blobs, result);

    {
        Ctx ctx;
        v1::HeartbeatRequest req;
        req.set_worker_id(first);
        req.set_task_id(stale.task_id());
        req.set_lease_id(stale.lease_id());
        v1::HeartbeatResponse resp;
        grpc::Status st = s.workers->Heartbeat(&ctx, req, &resp);
        EXPECT_TRUE(!st.ok() || !resp.lease_valid()) << "an expired lease was reported valid";
    }
    st = complete(first, stale, hash);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << StatusText(st);
    EXPECT_NE(st.error_message().find("lease"), std::string::npos) << st.error_message();

    st = complete(second, current, hash);
    EXPECT_TRUE(st.ok()) << StatusText(st);
    v1::JobStatus status;
    ASSERT_TRUE(WaitDone(s, job_id, &status));
    EXPECT_EQ(status.tasks_done(), 1);
    ExpectSameImage(RenderLocal(one_tile), Download(s, job_id, 0));
}

// Each bad request gets the status the contract names and a message about the problem;
// the coordinator goes on serving.
TEST_F(FarmTest, BadRequestsGetTheRightStatus) {
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    Stubs s(port);
    std::string good = SubmitCornell(s, kSmall);
    ASSERT_FALSE(good.empty());

    // A valid spec to spoil, one field at a time.
    v1::JobSpec base;
    base.set_name("bad");
    for (const BundleEntry& e : CollectBundle(kCornell)) {
        if (base.scene_path().empty()) base.set_scene_path(e.path);
        v1::BundleFile* f = base.add_files();
        f->set_path(e.path);
        f->set_hash(e.hash);
        f->set_size(e.size);
    }
    *base.mutable_options() = OptionsFromArgs(kSmall);

    auto still_serving = [&](const std::string& after) {
        Ctx ctx;
        v1::GetJobRequest req;
        req.set_job_id(good);
        v1::JobStatus status;
        grpc::Status st = s.farm->GetJob(&ctx, req, &status);
        EXPECT_TRUE(st.ok()) << "after " << after << ": " << StatusText(st);
    };
    auto expect_submit = [&](const std::string& what, const v1::JobSpec& spec,
                             std::vector<grpc::StatusCode> codes,
                             std::vector<std::string> mentions) {
        Ctx ctx;
        v1::SubmitJobRequest req;
        *req.mutable_spec() = spec;
        v1::SubmitJobResponse resp;
        grpc::Status st = s.farm->SubmitJob(&ctx, req, &resp);
        EXPECT_NE(std::find(codes.begin(), codes.end(), st.error_code()), codes.end())
            << what << ": " << StatusText(st);
        bool mentioned = false;
        for (const std::string& m : mentions)
            mentioned |= st.error_message().find(m) != std::string::npos;
        EXPECT_TRUE(mentioned) << what << ": the message does not mention " << Join(mentions)
                               << ": " << st.error_message();
        still_serving(what);
    };

    // An id like the coordinator's own that names no job; and one that is no id at all.
    const std::string unknown_id = "job-987654";
    {
        Ctx ctx;
        v1::GetJobRequest req;
        req.set_job_id(unknown_id);
        v1::JobStatus status;
        grpc::Status st = s.farm->GetJob(&ctx, req, &status);
        EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND) << StatusText(st);
        EXPECT_NE(st.error_message().find(unknown_id), std::string::npos) << st.error_message();
    }
    {
        Ctx ctx;
        v1::GetJobRequest req;
        req.set_job_id("no such job");
        v1::JobStatus status;
        grpc::Status st = s.farm->GetJob(&ctx, req, &status);
        EXPECT_TRUE(st.error_code() == grpc::StatusCode::NOT_FOUND ||
                    st.error_code() == grpc::StatusCode::INVALID_ARGUMENT)
            << StatusText(st);
        EXPECT_NE(st.error_message().find("no such job"), std::string::npos) << st.error_message();
    }
    {
        Ctx ctx;
        v1::CancelJobRequest req;
        req.set_job_id(unknown_id);
        v1::CancelJobResponse resp;
        grpc::Status st = s.farm->CancelJob(&ctx, req, &resp);
        EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND) << StatusText(st);
    }
    still_serving("unknown jobs");
    {
        // No worker runs, so the good job's frame is not done.
        Ctx ctx;
        v1::DownloadFrameRequest req;
        req.set_job_id(good);
        auto reader = s.farm->DownloadFrame(&ctx, req);
        v1::FileChunk chunk;
        while (reader->Read(&chunk)) {
        }
        EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
    }

    v1::JobSpec spec = base;
    spec.mutable_options()->set_spp(0);
    expect_submit("spp 0", spec, {grpc::StatusCode::INVALID_ARGUMENT}, {"spp"});
    spec.mutable_options()->set_spp(-3);
    expect_submit("spp -3", spec, {grpc::StatusCode::INVALID_ARGUMENT}, {"spp"});

    spec = base;
    spec.mutable_options()->set_width(1000000);
    spec.mutable_options()->set_height(1000000);
    expect_submit("a 10^6 x 10^6 image", spec,
                  {grpc::StatusCode::RESOURCE_EXHAUSTED, grpc::StatusCode::INVALID_ARGUMENT},
                  {"width", "height", "resolution", "1000000"});

    spec = base;
    spec.set_frame_start(5);
    spec.set_frame_end(2);
    expect_submit("frames 5-2", spec, {grpc::StatusCode::INVALID_ARGUMENT}, {"frame"});

    spec = base;
    std::string never = Sha256Hex("never uploaded");
    v1::BundleFile* extra = spec.add_files();
    extra->set_path("textures/missing.png");
    extra->set_hash(never);
    extra->set_size(14);
    expect_submit("a blob never uploaded", spec, {grpc::StatusCode::NOT_FOUND},
                  {never, "missing.png"});

    spec = base;
    spec.set_scene_path("../x.json");
    spec.mutable_files(0)->set_path("../x.json");
    expect_submit("a scene path escaping its folder", spec, {grpc::StatusCode::INVALID_ARGUMENT},
                  {"../x.json", "escape"});

    spec = base;
    spec.set_name("../../etc/passwd");
    expect_submit("a name that is a path", spec, {grpc::StatusCode::INVALID_ARGUMENT}, {"name"});

    {
        // Bytes that do not match the hash they claim.
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + 10s);
        v1::PutBlobResponse resp;
        auto writer = s.blobs->PutBlob(&ctx, &resp);
        v1::PutBlobRequest header;
        header.mutable_header()->set_hash(Sha256Hex("hello"));
        header.mutable_header()->set_size(5);
        writer->Write(header);
        v1::PutBlobRequest data;
        data.set_data("hellO");
        writer->Write(data);
        writer->WritesDone();
        grpc::Status st = writer->Finish();
        EXPECT_EQ(st.error_code(), grpc::StatusCode::DATA_LOSS) << StatusText(st);
        EXPECT_FALSE(st.error_message().empty());

        Ctx find_ctx;
        v1::FindMissingBlobsRequest find;
        find.add_hashes(Sha256Hex("hello"));
        v1::FindMissingBlobsResponse missing;
        ASSERT_TRUE(s.blobs->FindMissingBlobs(&find_ctx, find, &missing).ok());
        EXPECT_EQ(missing.missing_size(), 1) << "a corrupted upload was kept";
        still_serving("a corrupted blob");
    }

    // The command line reports the status by name and exits non-zero.
    std::string address = "127.0.0.1:" + std::to_string(port);
    CliResult unknown = Cli({"status", unknown_id, "--coordinator", address});
    EXPECT_NE(unknown.code, 0);
    EXPECT_NE(unknown.err.find("NOT_FOUND"), std::string::npos) << unknown.err;

    // A cancelled job ends `watch` with a failure status.
    CliResult cancel = Cli({"cancel", good, "--coordinator", address});
    EXPECT_EQ(cancel.code, 0) << cancel.err;
    CliResult watch = Cli({"watch", good, "--coordinator", address});
    EXPECT_NE(watch.code, 0);
    EXPECT_NE(watch.err.find("cancelled"), std::string::npos) << watch.err;
    still_serving("the cancellation");
}

// Multi-stage plans (photon batches, irradiance passes, tiles) on one, two and three
// workers, two jobs at once: every farm image equals the local render bit for bit,
// however the tasks of each stage were shared out.
TEST_F(FarmTest, StagedPlansMatchTheLocalRenderOnOneTwoAndThreeWorkers) {
    const std::vector<std::string> photon = Concat(kStagedSmall, kPhotonIc);
    const std::vector<std::string> irradiance = Concat(kStagedSmall, kIrradianceCache);
    const fs::path local_photon = RenderLocal(photon), local_irradiance = RenderLocal(irradiance);
    for (int workers = 1; workers <= 3; ++workers) {
        SCOPED_TRACE(std::to_string(workers) + " worker(s)");
        const std::string state = "state-" + std::to_string(workers);
        Process* coordinator = nullptr;
        int port = StartCoordinator(state, 0, 0, &coordinator);
        ASSERT_GT(port, 0);
        std::vector<Process*> started;
        for (int i = 1; i <= workers; ++i)
            started.push_back(&StartWorker(port, state + "-w" + std::to_string(i)));
        Stubs s(port);
        const std::string a = SubmitCornell(s, photon), b = SubmitCornell(s, irradiance);
        v1::JobStatus status;
        ASSERT_TRUE(WaitDone(s, a, &status));
        EXPECT_EQ(status.tasks_total(), 4 + 3 * 16);
        EXPECT_EQ(status.frames(0).stage(), "render");
        ExpectSameImage(local_photon, Download(s, a, 0));
        ASSERT_TRUE(WaitDone(s, b, &status));
        EXPECT_EQ(status.tasks_total(), 3 * 16);
        ExpectSameImage(local_irradiance, Download(s, b, 0));
        for (Process* p : started) p->Kill(SIGKILL);
        coordinator->Kill(SIGKILL);
    }
}

// `status` and `watch` say which stage a frame is in: here the photons, before any
// worker has come.
TEST_F(FarmTest, StatusAndWatchNameTheStage) {
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    const std::string address = "127.0.0.1:" + std::to_string(port);
    const std::vector<std::string> args = Concat(kStagedSmall, kPhotonIc);
    CliResult submit =
        Cli(Concat({"submit", kCornell, "--coordinator", address, "--name", "staged"}, args));
    ASSERT_EQ(submit.code, 0) << submit.err;
    const std::string job_id = Trim(submit.out);
    CliResult status = Cli({"status", job_id, "--coordinator", address});
    EXPECT_EQ(status.code, 0) << status.err;
    EXPECT_NE(status.out.find("photons 0/4"), std::string::npos) << status.out;

    Process& watch = Start({TESSERA_CLI, "watch", job_id, "--coordinator", address}, "watch");
    auto deadline = Clock::now() + 30s;
    while (ReadFile(dir_ / "watch.log").find("photons 0/4") == std::string::npos &&
           watch.Running() && Clock::now() < deadline)
        std::this_thread::sleep_for(20ms);
    EXPECT_NE(ReadFile(dir_ / "watch.log").find("photons 0/4"), std::string::npos)
        << ReadFile(dir_ / "watch.log");
    for (int i = 1; i <= 3; ++i) StartWorker(port, "w" + std::to_string(i));
    EXPECT_EQ(watch.Wait(240s), 0) << ReadFile(dir_ / "watch.log");

    fs::path out = dir_ / "frames";
    CliResult fetch = Cli({"fetch", job_id, "-o", out.string(), "--coordinator", address});
    ASSERT_EQ(fetch.code, 0) << fetch.err;
    ExpectSameImage(RenderLocal(args), out / "staged.0000.exr");
}

// `tessera farm` takes the same render options as `tessera render`: two frames of an
// irradiance-cache animation, each planned and merged on its own.
TEST_F(FarmTest, FarmCommandRendersStagedFrames) {
    const std::vector<std::string> args = Concat(kStagedSmall, kIrradianceCache);
    fs::path out = dir_ / "frames";
    CliResult farm =
        Cli(Concat({"farm", kCornell, "--workers", "2", "--threads-per-worker", "1", "--frames",
                    "0-1", "-o", out.string(), "--keep-state", (dir_ / "farm-state").string()},
                   args),
            240s);
    ASSERT_EQ(farm.code, 0) << farm.err;
    ExpectSameImage(RenderLocal(args, 0), out / "cornell-box.0000.exr");
    ExpectSameImage(RenderLocal(args, 1), out / "cornell-box.0001.exr");
}

// A worker killed while it holds a task of an irradiance pass: its lease expires, the
// task runs elsewhere, and the merged cache and the image are the same.
TEST_F(FarmTest, WorkerKilledMidStageDoesNotChangeTheImage) {
    int port = StartCoordinator("state", 0, 1500);
    ASSERT_GT(port, 0);
    Process& doomed = StartWorker(port, "doomed");
    StartWorker(port, "survivor");
    Stubs s(port);
    const std::vector<std::string> args = Concat(kStagedMedium, kPhotonIc);
    std::string job_id = SubmitCornell(s, args);
    v1::JobStatus status;
    // Both workers (one thread each) at work in the middle of the second pass.
    ASSERT_TRUE(PollJob(
        s, job_id,
        [](const v1::JobStatus& j) {
            const v1::FrameStatus& f = j.frames(0);
            return f.stage() == "irradiance-2" && f.stage_done() >= 1 &&
                   f.stage_done() < f.stage_total() - 2 && j.leases_granted() - j.tasks_done() >= 2;
        },
        180s, &status))
        << status.ShortDebugString();
    doomed.Kill(SIGKILL);
    std::printf("killed a worker at %s %d/%d\n", status.frames(0).stage().c_str(),
                status.frames(0).stage_done(), status.frames(0).stage_total());
    ASSERT_TRUE(WaitDone(s, job_id, &status));
    EXPECT_GE(status.leases_granted(), status.tasks_total());
    ExpectSameImage(RenderLocal(args), Download(s, job_id, 0));
}

// The coordinator killed right after it merged the photon maps: the restarted one
// keeps the merged maps (durable, recorded with the release of the next stage), does
// not shoot the photons again, and finishes the same image.
TEST_F(FarmTest, CoordinatorKilledBetweenStagesKeepsTheMergedStages) {
    // Leases long enough that a worker slowed down by a loaded machine keeps them: the
    // count of leases below is then exact however slow the run.
    constexpr int kLeaseMs = 5000;
    Process* coordinator = nullptr;
    int port = StartCoordinator("state", 0, kLeaseMs, &coordinator);
    ASSERT_GT(port, 0);
    constexpr int kWorkers = 2;
    for (int i = 1; i <= kWorkers; ++i) StartWorker(port, "w" + std::to_string(i));
    const std::vector<std::string> args = Concat(kStagedMedium, kPhotonIc);
    std::string job_id;
    v1::JobStatus before;
    {
        Stubs s(port);
        job_id = SubmitCornell(s, args);
        ASSERT_TRUE(PollJob(
            s, job_id,
            [](const v1::JobStatus& j) {
                const std::string& stage = j.frames(0).stage();
                return !stage.empty() && stage != "photons";
            },
            180s, &before))
            << before.ShortDebugString();
    }
    coordinator->Kill(SIGKILL);
    ASSERT_NE(before.frames(0).stage(), "render") << "the kill came too late to test anything";
    ASSERT_EQ(StartCoordinator("state", port, kLeaseMs), port);
    Stubs s(port);
    v1::JobStatus after;
    ASSERT_TRUE(PollJob(
        s, job_id, [](const v1::JobStatus&) { return true; }, 120s, &after));
    EXPECT_NE(after.frames(0).stage(), "photons") << "the merged photon maps were lost";
    EXPECT_GE(after.tasks_done(), before.tasks_done());
    ASSERT_TRUE(WaitDone(s, job_id, &after));
    std::printf("killed at %s %d/%d; tasks %d, leases granted %lld\n",
                before.frames(0).stage().c_str(), before.frames(0).stage_done(),
                before.frames(0).stage_total(), after.tasks_total(),
                static_cast<long long>(after.leases_granted()));
    // Only the tasks in flight at the kill may run again (one per worker thread, and
    // perhaps once more each if the restart outlived a lease): no batch nor pass again.
    EXPECT_LE(after.leases_granted(), after.tasks_total() + 2 * kWorkers);
    ExpectSameImage(RenderLocal(args), Download(s, job_id, 0));
}

// A second coordinator on the port the first one listens on refuses to start, before it
// opens its state, and says why (gRPC's default SO_REUSEPORT would let both listen, each
// answering some of the calls); the first goes on serving.
TEST_F(FarmTest, SecondCoordinatorOnATakenPortRefusesToStart) {
    Process* first = nullptr;
    const int port = StartCoordinator("first", 0, 0, &first);
    ASSERT_GT(port, 0);
    Process& second =
        Start({TESSERA_COORDINATOR, "--listen", "127.0.0.1:" + std::to_string(port), "--state",
               (dir_ / "second").string(), "--output", (dir_ / "second-frames").string()},
              "second");
    const int code = second.Wait(120s);
    EXPECT_NE(code, -1) << "the second coordinator is still running";
    EXPECT_NE(code, 0);
    const std::string log = ReadFile(dir_ / "second.log");
    EXPECT_NE(
        log.find("port " + std::to_string(port) + " on 127.0.0.1 is in use by another process"),
        std::string::npos)
        << log;
    EXPECT_FALSE(fs::exists(dir_ / "second" / "tessera.db")) << "its state was opened";

    ASSERT_TRUE(first->Running());
    StartWorker(port, "w1");
    Stubs s(port);
    const std::string job_id = SubmitCornell(s, kSmall);
    v1::JobStatus last;
    EXPECT_TRUE(WaitDone(s, job_id, &last));
}

// A worker given no --coordinator takes $TESSERA_COORDINATOR, as the CLI does.
TEST_F(FarmTest, WorkerTakesTheCoordinatorFromTheEnvironment) {
    const int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    std::vector<std::string> worker = WorkerArgv(port, "from-env");
    ASSERT_EQ(worker.at(1), "--coordinator");
    worker.erase(worker.begin() + 1, worker.begin() + 3);
    // Set for the worker alone, through env(1): the test's own environment stays as it is.
    worker.insert(worker.begin(), {"/usr/bin/env", "-u", "TESSERA_COORDINATOR",
                                   "TESSERA_COORDINATOR=127.0.0.1:" + std::to_string(port)});
    Start(worker, "from-env");
    Stubs s(port);
    const std::string job_id = SubmitCornell(s, kSmall);
    v1::JobStatus last;
    EXPECT_TRUE(WaitDone(s, job_id, &last)) << ReadFile(dir_ / "from-env.log");
    Ctx ctx;
    v1::ListWorkersResponse workers;
    ASSERT_TRUE(s.farm->ListWorkers(&ctx, v1::ListWorkersRequest(), &workers).ok());
    ASSERT_EQ(workers.workers_size(), 1);
    EXPECT_EQ(workers.workers(0).name(), "from-env");
}

// A coordinator address without a port means port 50051, for the worker and the CLI.
// The steering commands end to end: a disabled worker takes nothing, a job's priority
// changes, a cancelled job is retried and renders the local image, its log tells what
// happened, it is deleted; the worker's reported totals reach `tessera workers`.
TEST_F(FarmTest, SteeringCommandsDriveTheFarm) {
    int port = StartCoordinator("state");
    ASSERT_GT(port, 0);
    const std::string address = "127.0.0.1:" + std::to_string(port);
    StartWorker(port, "w1", 2);
    Stubs s(port);
    auto worker_state = [&](const std::string& name) {
        v1::ListWorkersResponse r;
        Ctx ctx;
        s.farm->ListWorkers(&ctx, v1::ListWorkersRequest(), &r);
        for (const v1::WorkerStatus& w : r.workers())
            if (w.name() == name) return w;
        return v1::WorkerStatus();
    };
    for (auto deadline = Clock::now() + 120s;
         worker_state("w1").name().empty() && Clock::now() < deadline;)
        std::this_thread::sleep_for(20ms);
    ASSERT_FALSE(worker_state("w1").name().empty()) << "the worker never registered";
    CliResult disable = Cli({"workers", "disable", "w1", "--coordinator", address});
    ASSERT_EQ(disable.code, 0) << disable.err;
    EXPECT_NE(disable.err.find("disabled"), std::string::npos) << disable.err;
    CliResult unknown = Cli({"workers", "disable", "w9", "--coordinator", address});
    EXPECT_EQ(unknown.code, 1);
    EXPECT_NE(unknown.err.find("NOT_FOUND"), std::string::npos) << unknown.err;

    CliResult submit = Cli(Concat({"submit", kCornell, "--coordinator", address}, kSmall));
    ASSERT_EQ(submit.code, 0) << submit.err;
    const std::string job = Trim(submit.out);
    CliResult priority = Cli({"priority", job, "7", "--coordinator", address});
    ASSERT_EQ(priority.code, 0) << priority.err;
    // The worker, disabled, has leased nothing (it polls every few hundred ms).
    std::this_thread::sleep_for(1500ms);
    CliResult status = Cli({"status", job, "--coordinator", address});
    EXPECT_NE(status.out.find("QUEUED"), std::string::npos) << status.out;
    EXPECT_NE(status.out.find("priority   7"), std::string::npos) << status.out;
    CliResult workers = Cli({"workers", "--coordinator", address});
    EXPECT_NE(workers.out.find("disabled"), std::string::npos) << workers.out;

    ASSERT_EQ(Cli({"cancel", job, "--coordinator", address}).code, 0);
    CliResult retry = Cli({"retry", job, "--coordinator", address});
    ASSERT_EQ(retry.code, 0) << retry.err;
    ASSERT_EQ(Cli({"workers", "enable", "w1", "--coordinator", address}).code, 0);
    CliResult watch = Cli({"watch", job, "--quiet", "--coordinator", address});
    ASSERT_EQ(watch.code, 0) << watch.err;
    fs::path out = dir_ / "frames";
    ASSERT_EQ(Cli({"fetch", job, "-o", out.string(), "--coordinator", address}).code, 0);
    ExpectSameImage(RenderLocal(kSmall), out / "cornell-box.0000.exr");
    CliResult again = Cli({"retry", job, "--coordinator", address});
    EXPECT_EQ(again.code, 1);
    EXPECT_NE(again.err.find("FAILED_PRECONDITION"), std::string::npos) << again.err;

    // The worker sends its totals with its next heartbeats: 64 x 64 pixels x 4 samples,
    // and the rays they took.
    for (auto deadline = Clock::now() + 60s;
         worker_state("w1").samples_done() < 64 * 64 * 4 && Clock::now() < deadline;)
        std::this_thread::sleep_for(50ms);
    const v1::WorkerStatus w1 = worker_state("w1");
    EXPECT_GE(w1.samples_done(), 64 * 64 * 4);
    EXPECT_GT(w1.rays_traced(), w1.samples_done());
    EXPECT_EQ(w1.tasks_done(), 16);

    CliResult logs = Cli({"logs", job, "--coordinator", address});
    ASSERT_EQ(logs.code, 0) << logs.err;
    for (const char* kind :
         {"submitted", "priority", "cancelled", "retried", "done", "frame", "job-done"})
        EXPECT_NE(logs.out.find(std::string("  ") + kind + " "), std::string::npos) << kind << "\n"
                                                                                    << logs.out;
    CliResult task = Cli({"logs", job, "--task", "3", "--coordinator", address});
    ASSERT_EQ(task.code, 0) << task.err;
    EXPECT_NE(task.out.find("task 3 (frame 0 render 3) on w1 attempt 1"), std::string::npos)
        << task.out;
    EXPECT_EQ(task.out.find("task 4"), std::string::npos) << task.out;

    CliResult del = Cli({"delete", job, "--coordinator", address});
    ASSERT_EQ(del.code, 0) << del.err;
    EXPECT_NE(del.err.find("deleted"), std::string::npos) << del.err;
    CliResult gone = Cli({"status", job, "--coordinator", address});
    EXPECT_EQ(gone.code, 1);
    EXPECT_NE(gone.err.find("NOT_FOUND"), std::string::npos) << gone.err;
    EXPECT_TRUE(fs::exists(dir_ / "state-frames" / job / "cornell-box.0000.exr"))
        << "delete removed a written frame";
}

TEST(CoordinatorAddress, HostAloneMeansTheDefaultPort) {
    EXPECT_EQ(WithDefaultPort("farm.example.com"), "farm.example.com:50051");
    EXPECT_EQ(WithDefaultPort("127.0.0.1"), "127.0.0.1:50051");
    EXPECT_EQ(WithDefaultPort("127.0.0.1:7000"), "127.0.0.1:7000");
    EXPECT_EQ(WithDefaultPort("127.0.0.1:0"), "127.0.0.1:0");
    EXPECT_EQ(WithDefaultPort("[::1]"), "[::1]:50051");
    EXPECT_EQ(WithDefaultPort("::1"), "[::1]:50051");
    EXPECT_EQ(WithDefaultPort("[::1]:7000"), "[::1]:7000");
    EXPECT_EQ(WithDefaultPort("unix:/run/tessera.sock"), "unix:/run/tessera.sock");
    EXPECT_EQ(WithDefaultPort("dns:///farm:7000"), "dns:///farm:7000");
    for (const char* bad : {"", "farm:", "farm:http", "farm:70000", "[::1", "[::1]7000"})
        EXPECT_THROW(WithDefaultPort(bad), std::invalid_argument) << bad;
}

}  // namespace
}  // namespace tessera
