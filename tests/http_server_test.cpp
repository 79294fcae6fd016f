// The coordinator's dashboard over HTTP (http_server.h) against a Coordinator in this
// process: the page and its assets, the JSON API's shapes, the buttons' POSTs, errors as
// JSON, the live preview of a partly rendered frame, who may listen where, tokens and
// cookies, HTTPS with the coordinator's certificate, and /metrics. Requests go through a
// real socket on 127.0.0.1 (cpp-httplib's client).

#include "http_server.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <nlohmann/json.hpp>

#include "certificates.h"
#include "convert.h"
#include "coordinator.h"
#include "coordinator_fixtures.h"
#include "core/arena.h"
#include "io/image_io.h"
#include "metrics.h"
#include "plan/frame_renderer.h"
#include "plan/render_plan.h"
#include "preview.h"
#include "scene/scene_loader.h"
#include "sha256.h"
#include "temp_dir.h"
#include "test_logs.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::kClientToken;
using test::kWorkerToken;
using test::ReadFile;

::testing::Environment* const kQuietLogs = test::QuietLogs(spdlog::level::err);

// 32x32 pixels in 8-pixel tiles: 16 render tasks per frame, under a bright sky so that
// every rendered pixel is lit.
const std::string kScene =
    test::SphereUnderSkyScene({.width = 32, .height = 32, .spp = 2, .max_depth = 2});
constexpr int kTiles = 16;

class HttpServerTest : public test::TempDirTest {
  protected:
    void SetUp() override {
        TempDirTest::SetUp();
        options_.state_dir = (dir_ / "state").string();
        options_.output_dir = (dir_ / "out").string();
        options_.scheduler.lease_ms = 120000;  // the test completes tasks itself, slowly
        options_.sweep_interval_ms = 20;
        scene_path_ = dir_ / "scene.json";
        std::ofstream(scene_path_) << kScene;
        coordinator_ = std::make_unique<Coordinator>(options_, clock_);
        coordinator_->Start();
    }
    void TearDown() override {
        http_.reset();
        coordinator_->StopWaiting();
        coordinator_->Stop();
        coordinator_.reset();
        TempDirTest::TearDown();
    }

    // Starts the dashboard on 127.0.0.1, any port; returns a client of it.
    httplib::Client& Serve(const Authenticator& auth = OpenAccess(),
                           std::function<std::string()> metrics = {}) {
        http_ = std::make_unique<HttpServer>(*coordinator_, auth, std::move(metrics));
        HttpServerOptions options;
        options.listen = "127.0.0.1:0";
        port_ = http_->Start(options);
        client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
        client_->set_read_timeout(60);
        return *client_;
    }

    std::string Submit(int frames = 1) {
        v1::JobSpec spec = test::SceneJob(*coordinator_, kScene, frames);
        spec.set_name("ball");
        return coordinator_->SubmitJob(spec);
    }

    std::optional<LeasedTask> Lease(const std::string& worker) {
        return test::LeaseNow(*coordinator_, worker);
    }

    // Leases and completes up to `count` tasks as a worker would (rendering them here).
    int RenderTasks(const std::string& worker, int count) {
        int done = 0;
        for (; done < count; ++done) {
            std::optional<LeasedTask> task = Lease(worker);
            if (!task) break;
            if (!loaded_.scene)
                loaded_ = LoadSceneFile(scene_path_.string(), FromProto(task->spec->options()));
            RenderSettings settings = loaded_.settings;
            settings.frame = task->frame;
            FrameRenderer renderer(*loaded_.scene, settings);
            const int stage = renderer.Plan().StageIndex(task->stage);
            ArtifactSet artifacts(renderer.Plan().stages.size());
            ScratchBuffer arena;
            const std::string result = renderer.RunTask(stage, task->task_index, artifacts, arena);
            coordinator_->CompleteTask(worker, task->task_id, task->lease_id, task->lease_token, "",
                                       result);
        }
        return done;
    }

    v1::JobStatus WaitFinished(const std::string& job) {
        v1::JobStatus status;
        for (int i = 0; i < 12000; ++i) {
            status = coordinator_->GetJob(job);
            if (status.state() >= v1::JOB_STATE_DONE) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        return status;
    }

    static json Json(const httplib::Result& r) {
        EXPECT_TRUE(r) << "no response";
        if (!r) return json();
        EXPECT_EQ(r->get_header_value("Content-Type"), "application/json") << r->body;
        return json::parse(r->body, nullptr, false);
    }

    // The PNG in `bytes`, read back through a file.
    Image ReadPng(const std::string& bytes) {
        const fs::path path = dir_ / ("read-" + std::to_string(++pngs_) + ".png");
        std::ofstream(path, std::ios::binary) << bytes;
        return ReadImage(path.string());
    }

    SystemClock clock_;
    CoordinatorOptions options_;
    fs::path scene_path_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<HttpServer> http_;
    std::unique_ptr<httplib::Client> client_;
    int port_ = 0;
    LoadedScene loaded_;
    int pngs_ = 0;
};

TEST_F(HttpServerTest, ServesThePageAndItsAssetsAsBuiltIn) {
    httplib::Client& c = Serve();
    EXPECT_EQ(http_->Url(), "http://127.0.0.1:" + std::to_string(port_) + "/");
    const fs::path assets = fs::path(TESSERA_SOURCE_DIR) / "coordinator" / "dashboard";
    for (const auto& [path, file, type] :
         std::vector<std::tuple<std::string, std::string, std::string>>{
             {"/", "index.html", "text/html"},
             {"/app.js", "app.js", "text/javascript"},
             {"/style.css", "style.css", "text/css"}}) {
        httplib::Result r = c.Get(path.c_str());
        ASSERT_TRUE(r) << path;
        EXPECT_EQ(r->status, 200) << path;
        EXPECT_EQ(r->get_header_value("Content-Type").rfind(type, 0), 0u) << path;
        EXPECT_EQ(r->body, ReadFile(assets / file)) << path << " is not the file's bytes";
    }
    const std::string page = c.Get("/")->body;
    for (const char* id : {"id=\"jobs\"", "id=\"workers\"", "id=\"preview\"", "id=\"frames\"",
                           "id=\"failures\"", "id=\"log\""})
        EXPECT_NE(page.find(id), std::string::npos) << id;
    EXPECT_EQ(page.find("https://"), std::string::npos) << "no external resources";
    EXPECT_EQ(c.Get("/index.html")->status, 404);
    EXPECT_EQ(c.Get("/../../etc/passwd")->status, 404);
}

TEST_F(HttpServerTest, ApiListsJobsFramesWorkersAndTheLog) {
    httplib::Client& c = Serve();
    json empty = Json(c.Get("/api/jobs"));
    EXPECT_EQ(empty["jobs"], json::array());
    EXPECT_GT(empty["now_unix_ms"].get<int64_t>(), 0);

    const std::string job = Submit(2);
    const std::string worker = coordinator_->Register("w1", 2).worker_id;
    ASSERT_EQ(RenderTasks(worker, 3), 3);

    json jobs = Json(c.Get("/api/jobs"));
    ASSERT_EQ(jobs["jobs"].size(), 1u) << jobs.dump();
    const json& j = jobs["jobs"][0];
    EXPECT_EQ(j["job_id"], job);
    EXPECT_EQ(j["name"], "ball");
    EXPECT_EQ(j["state"], "RUNNING");
    EXPECT_EQ(j["priority"], 0);
    EXPECT_EQ(j["tasks_done"], 3);
    EXPECT_EQ(j["tasks_total"], 2 * kTiles);
    EXPECT_DOUBLE_EQ(j["progress"].get<double>(), 3.0 / (2 * kTiles));
    EXPECT_EQ(j["current_frame"], 0);
    EXPECT_EQ(j["stage_label"], "render");
    EXPECT_EQ(j["width"], 32);
    EXPECT_EQ(j["failures"], json::array());
    ASSERT_EQ(j["frames"].size(), 2u);
    const json& f = j["frames"][0];
    EXPECT_EQ(f["frame"], 0);
    EXPECT_EQ(f["state"], "RENDERING");
    EXPECT_EQ(f["stage"], "render");
    EXPECT_EQ(f["stage_label"], "render");
    EXPECT_EQ(f["stage_done"], 3);
    EXPECT_EQ(f["stage_total"], kTiles);
    EXPECT_EQ(j["frames"][1]["state"], "PENDING");

    // One job by id, also written with leading zeros.
    EXPECT_EQ(Json(c.Get(("/api/jobs/" + job).c_str())), j);
    const std::string padded = "job-00000" + job.substr(job.find('-') + 1);
    EXPECT_EQ(Json(c.Get(("/api/jobs/" + padded).c_str()))["job_id"], job);

    json workers = Json(c.Get("/api/workers"));
    ASSERT_EQ(workers["workers"].size(), 1u);
    const json& w = workers["workers"][0];
    EXPECT_EQ(w["name"], "w1");
    EXPECT_EQ(w["threads"], 2);
    EXPECT_EQ(w["tasks_done"], 3);
    EXPECT_EQ(w["disabled"], false);
    for (const char* field : {"state", "current_task", "rays_per_second", "samples_per_second",
                              "last_seen_unix_ms", "tasks_leased"})
        EXPECT_TRUE(w.contains(field)) << field;

    json log = Json(c.Get(("/api/jobs/" + job + "/log").c_str()));
    ASSERT_FALSE(log["entries"].empty());
    EXPECT_EQ(log["entries"][0]["kind"], "submitted");
    json task_log = Json(c.Get(("/api/jobs/" + job + "/log?task=1&limit=5").c_str()));
    ASSERT_FALSE(task_log["entries"].empty());
    for (const json& e : task_log["entries"]) EXPECT_EQ(e["task"], 1) << e.dump();
    json last = Json(c.Get(("/api/jobs/" + job + "/log?limit=1").c_str()));
    EXPECT_EQ(last["entries"].size(), 1u);
}

TEST_F(HttpServerTest, ButtonsPostCancelRetryPriorityAndWorkerSwitches) {
    httplib::Client& c = Serve();
    const std::string job = Submit();
    const std::string base = "/api/jobs/" + job;

    httplib::Result r =
        c.Post((base + "/priority").c_str(), R"({"priority": 7})", "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(Json(r)["priority"], 7);
    EXPECT_EQ(coordinator_->GetJob(job).priority(), 7);

    for (const char* bad : {"", "{", "[]", R"({"priority": "high"})", R"({"priority": 1.5})",
                            R"({"priority": 99999999999})", R"({"other": 1})"}) {
        httplib::Result b = c.Post((base + "/priority").c_str(), bad, "application/json");
        ASSERT_TRUE(b) << bad;
        EXPECT_EQ(b->status, 400) << bad << ": " << b->body;
        EXPECT_TRUE(Json(b).contains("error")) << bad;
    }

    r = c.Post((base + "/cancel").c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(Json(r)["state"], "CANCELLED");
    EXPECT_EQ(coordinator_->GetJob(job).state(), v1::JOB_STATE_CANCELLED);
    // A finished job's priority cannot change: 409.
    r = c.Post((base + "/priority").c_str(), R"({"priority": 1})", "application/json");
    EXPECT_EQ(r->status, 409) << r->body;

    r = c.Post((base + "/retry").c_str());
    EXPECT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(Json(r)["state"], "QUEUED");
    r = c.Post((base + "/retry").c_str());
    EXPECT_EQ(r->status, 409) << "a queued job has nothing to retry: " << r->body;
    EXPECT_EQ(c.Get((base + "/cancel").c_str())->status, 404) << "cancel is a POST";

    coordinator_->Register("w1", 1);
    r = c.Post("/api/workers/w1/disable");
    EXPECT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(Json(r)["disabled"], true);
    EXPECT_TRUE(coordinator_->ListWorkers().at(0).disabled());
    r = c.Post("/api/workers/w1/enable");
    EXPECT_EQ(Json(r)["disabled"], false);
    EXPECT_FALSE(coordinator_->ListWorkers().at(0).disabled());
}

TEST_F(HttpServerTest, BadRequestsAreJsonErrorsWithTheirStatus) {
    httplib::Client& c = Serve();
    const std::string job = Submit();
    auto expect = [&](httplib::Result r, int status, const std::string& what) {
        ASSERT_TRUE(r) << what;
        EXPECT_EQ(r->status, status) << what << ": " << r->body;
        json body = Json(r);
        EXPECT_TRUE(body.contains("error") && !body["error"].get<std::string>().empty())
            << what << ": " << r->body;
    };
    expect(c.Get("/api/jobs/job-999999"), 404, "unknown job");
    expect(c.Get("/api/jobs/not-a-job"), 404, "malformed job id");
    expect(c.Get("/api/jobs/job-999999/log"), 404, "log of an unknown job");
    expect(c.Post("/api/jobs/job-999999/cancel"), 404, "cancel of an unknown job");
    expect(c.Post("/api/jobs/%00/retry"), 404, "a NUL in the id");
    expect(c.Get(("/api/jobs/" + job + "/log?task=abc").c_str()), 400, "task not a number");
    expect(c.Get(("/api/jobs/" + job + "/log?task=-1").c_str()), 400, "negative task");
    expect(c.Get(("/api/jobs/" + job + "/log?task=999999").c_str()), 400, "task out of range");
    expect(c.Get(("/api/jobs/" + job + "/log?limit=0").c_str()), 400, "limit 0");
    expect(c.Get(("/api/jobs/" + job + "/frames/7/preview.png").c_str()), 404, "no frame 7");
    expect(c.Get(("/api/jobs/" + job + "/frames/x/preview.png").c_str()), 404, "frame x");
    expect(c.Get(("/api/jobs/" + job + "/frames/99999999999/preview.png").c_str()), 404,
           "huge frame");
    expect(c.Get("/api/jobs/job-999999/frames/0/preview.png"), 404, "preview of no job");
    expect(c.Post("/api/workers/nobody/disable"), 404, "unknown worker");
    expect(c.Get("/api/nothing"), 404, "unknown route");
    expect(c.Delete(("/api/jobs/" + job).c_str()), 404, "no DELETE");
    expect(c.Get("/metrics"), 404, "no metrics given");
    // Still serving.
    EXPECT_EQ(c.Get("/api/jobs")->status, 200);
}

TEST_F(HttpServerTest, PreviewShowsTheTilesDoneSoFarAndTheFinishedFrame) {
    httplib::Client& c = Serve();
    const std::string job = Submit();
    const std::string url = "/api/jobs/" + job + "/frames/0/preview.png";

    // Queued, nothing rendered: dark, at the job's size.
    httplib::Result r = c.Get(url.c_str());
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "image/png");
    Image dark = ReadPng(r->body);
    ASSERT_EQ(dark.width, 32);
    ASSERT_EQ(dark.height, 32);
    for (float v : dark.pixels) ASSERT_EQ(v, 0.0f);

    // Tasks are leased in tile order: the top two rows of 4x4 tiles are done.
    const std::string worker = coordinator_->Register("w1", 1).worker_id;
    ASSERT_EQ(RenderTasks(worker, kTiles / 2), kTiles / 2);
    r = c.Get(url.c_str());
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(r->get_header_value("X-Tessera-Results"), "8/16");
    EXPECT_EQ(r->get_header_value("X-Tessera-Final"), "0");
    const std::string partial_png = r->body;
    Image partial = ReadPng(partial_png);
    ASSERT_EQ(partial.width, 32);
    ASSERT_EQ(partial.height, 32);
    const int red = partial.ChannelIndex("R");
    ASSERT_GE(red, 0);
    for (int tile = 0; tile < kTiles; ++tile) {
        // The tile's centre, away from the filter's apron that reaches into neighbours.
        const int x = (tile % 4) * 8 + 4, y = (tile / 4) * 8 + 4;
        float sum = 0;
        for (int ch = 0; ch < 3; ++ch) sum += partial.At(x, y, red + ch);
        if (tile < kTiles / 2)
            EXPECT_GT(sum, 0.05f) << "tile " << tile << " is done but dark";
        else
            EXPECT_EQ(sum, 0.0f) << "tile " << tile << " is not done but shows";
    }
    // Unchanged results: the cached preview.
    EXPECT_EQ(c.Get(url.c_str())->body, partial_png);

    ASSERT_EQ(RenderTasks(worker, kTiles), kTiles / 2);
    ASSERT_EQ(WaitFinished(job).state(), v1::JOB_STATE_DONE);
    r = c.Get(url.c_str());
    ASSERT_EQ(r->status, 200);
    EXPECT_EQ(r->get_header_value("X-Tessera-Final"), "1");
    EXPECT_EQ(r->body, ReadFile(coordinator_->FrameFile(job, 0, true)));
}

TEST_F(HttpServerTest, PartialAssemblySumsTilesAsTheWrittenFrameDoes) {
    const std::string job = Submit();
    const std::string worker = coordinator_->Register("w1", 1).worker_id;
    ASSERT_EQ(RenderTasks(worker, kTiles - 1), kTiles - 1);
    // One tile short of the frame (the job is still running: its results are readable).
    const FrameAssemblyInput in = coordinator_->GetScheduler().GetAssemblyInput(job, 0);
    ASSERT_TRUE(in.job_running);
    int used = 0;
    const Image almost = AssemblePartialFrame(in, coordinator_->Blobs(), &used);
    EXPECT_EQ(used, kTiles - 1);
    ASSERT_EQ(RenderTasks(worker, 1), 1);
    ASSERT_EQ(WaitFinished(job).state(), v1::JOB_STATE_DONE);
    const Image written = ReadImage(coordinator_->FrameFile(job, 0, false));
    ASSERT_EQ(almost.width, written.width);
    ASSERT_EQ(almost.height, written.height);
    // The first tile is far from the last one and its apron: the same bits as written.
    const int r = written.ChannelIndex("R");
    ASSERT_EQ(almost.channels.at(0), "R");
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x)
            ASSERT_EQ(almost.At(x, y, 0), written.At(x, y, r)) << x << "," << y;
    EXPECT_EQ(almost.At(28, 28, 0), 0.0f) << "the last tile is not done";
    EXPECT_GT(written.At(28, 28, r), 0.0f);
}

TEST(DashboardOptions, OffLoopbackOnlyWithTlsAndTokens) {
    ListenSecurity none;
    EXPECT_TRUE(DashboardOptions("127.0.0.1:0", none, false).tls_cert_file.empty());
    EXPECT_NO_THROW(DashboardOptions("localhost:8080", none, false));
    EXPECT_NO_THROW(DashboardOptions("[::1]:8080", none, false));

    auto refusal = [](const std::string& listen, const ListenSecurity& s, bool tokens) {
        try {
            DashboardOptions(listen, s, tokens);
        } catch (const std::runtime_error& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    ListenSecurity tls;
    tls.tls_cert_file = "server.pem";
    tls.tls_key_file = "server.key";
    std::string why = refusal("0.0.0.0:8080", none, false);
    EXPECT_NE(why.find("TLS"), std::string::npos) << why;
    EXPECT_NE(why.find("tokens"), std::string::npos) << why;
    why = refusal("0.0.0.0:8080", tls, false);
    EXPECT_NE(why.find("tokens (--tokens)"), std::string::npos) << why;
    EXPECT_EQ(why.find("TLS (--tls-cert"), std::string::npos) << why;
    why = refusal("10.1.2.3:8080", none, true);
    EXPECT_NE(why.find("TLS (--tls-cert"), std::string::npos) << why;
    ListenSecurity insecure = none;
    insecure.insecure = true;
    EXPECT_FALSE(refusal("0.0.0.0:8080", insecure, false).empty())
        << "--insecure does not open the dashboard";
    EXPECT_FALSE(refusal("unix:/tmp/socket", none, false).empty()) << "not HOST:PORT";

    HttpServerOptions o = DashboardOptions("0.0.0.0:8080", tls, true);
    EXPECT_EQ(o.listen, "0.0.0.0:8080");
    EXPECT_EQ(o.tls_cert_file, "server.pem");
    EXPECT_EQ(o.tls_key_file, "server.key");
    EXPECT_EQ(DashboardOptions("127.0.0.1:0", tls, false).tls_cert_file, "server.pem")
        << "HTTPS whenever the coordinator has a certificate";
}

TEST_F(HttpServerTest, WithTokensEveryRequestNeedsAClientToken) {
    const Authenticator auth = Authenticator::FromText(
        "client alice " + kClientToken + " max_priority=5\nworker render " + kWorkerToken + "\n",
        "tokens");
    httplib::Client& c = Serve(auth, [] { return std::string("tessera_up 1\n"); });
    const std::string job = Submit();
    const httplib::Headers client = {{"Authorization", "Bearer " + kClientToken}};
    const httplib::Headers worker = {{"Authorization", "Bearer " + kWorkerToken}};
    const httplib::Headers unknown = {{"Authorization", "Bearer not-a-token-of-this-farm"}};

    for (const char* path : {"/api/jobs", "/api/workers", "/metrics", "/app.js"}) {
        EXPECT_EQ(c.Get(path)->status, 401) << path;
        EXPECT_EQ(c.Get(path, unknown)->status, 401) << path;
        EXPECT_EQ(c.Get(path, worker)->status, 403) << path;
        EXPECT_EQ(c.Get(path, client)->status, 200) << path;
    }
    EXPECT_EQ(c.Get("/api/jobs")->get_header_value("WWW-Authenticate"), "Bearer");
    EXPECT_EQ(c.Post(("/api/jobs/" + job + "/cancel").c_str())->status, 401);
    EXPECT_EQ(c.Post(("/api/jobs/" + job + "/cancel").c_str(), worker, "", "text/plain")->status,
              403);
    EXPECT_EQ(coordinator_->GetJob(job).state(), v1::JOB_STATE_QUEUED);
    // The token's own limits hold.
    httplib::Result r = c.Post(("/api/jobs/" + job + "/priority").c_str(), client,
                               R"({"priority": 9})", "application/json");
    EXPECT_EQ(r->status, 400) << r->body;
    EXPECT_NE(r->body.find("alice"), std::string::npos) << r->body;

    // The page without a token: the login form.
    r = c.Get("/");
    EXPECT_EQ(r->status, 401);
    EXPECT_NE(r->body.find("<form method=\"post\" action=\"/login\""), std::string::npos);
    EXPECT_EQ(c.Get("/login")->status, 200);

    // A wrong token at the form: refused, no cookie.
    r = c.Post("/login", "token=worker-token-0123456789abcdef",
               "application/x-www-form-urlencoded");
    EXPECT_EQ(r->status, 403);
    EXPECT_FALSE(r->has_header("Set-Cookie"));
    // The right one: a cookie that opens the API, and back to the page.
    r = c.Post("/login", "token=" + kClientToken, "application/x-www-form-urlencoded");
    EXPECT_EQ(r->status, 303);
    EXPECT_EQ(r->get_header_value("Location"), "/");
    const std::string cookie = r->get_header_value("Set-Cookie");
    EXPECT_NE(cookie.find("HttpOnly"), std::string::npos) << cookie;
    EXPECT_NE(cookie.find("SameSite=Strict"), std::string::npos) << cookie;
    const httplib::Headers with_cookie = {
        {"Cookie", "other=1; " + cookie.substr(0, cookie.find(';'))}};
    EXPECT_EQ(c.Get("/api/jobs", with_cookie)->status, 200);
    EXPECT_EQ(c.Get("/", with_cookie)->status, 200);
    EXPECT_EQ(c.Get("/api/jobs", {{"Cookie", "tessera_token=wrong"}})->status, 401);
    // ?token= logs a browser in once and leaves the address bar.
    r = c.Get(("/?token=" + kClientToken).c_str());
    EXPECT_EQ(r->status, 303);
    EXPECT_EQ(r->get_header_value("Location"), "/");
    EXPECT_EQ(r->get_header_value("Set-Cookie"), cookie);
    r = c.Post(("/api/jobs/" + job + "/cancel").c_str(), with_cookie, "", "text/plain");
    EXPECT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(coordinator_->GetJob(job).state(), v1::JOB_STATE_CANCELLED);
}

TEST_F(HttpServerTest, ServesHttpsWithTheCoordinatorsCertificate) {
    const KeyAndCertificate ca = MakeCertificateAuthority("test CA", 1);
    const KeyAndCertificate server =
        MakeCertificate(ca, "localhost", {"localhost", "127.0.0.1"}, 1);
    std::ofstream(dir_ / "ca.pem") << ca.certificate_pem;
    std::ofstream(dir_ / "server.pem") << server.certificate_pem;
    std::ofstream(dir_ / "server.key") << server.key_pem;
    ListenSecurity tls;
    tls.tls_cert_file = (dir_ / "server.pem").string();
    tls.tls_key_file = (dir_ / "server.key").string();
    HttpServer https(*coordinator_, OpenAccess());
    const int port = https.Start(DashboardOptions("127.0.0.1:0", tls, false));
    EXPECT_EQ(https.Url(), "https://127.0.0.1:" + std::to_string(port) + "/");

    httplib::SSLClient c("127.0.0.1", port);
    c.set_ca_cert_path((dir_ / "ca.pem").string().c_str());
    c.enable_server_certificate_verification(true);
    httplib::Result r = c.Get("/api/jobs");
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 200);
    // Plaintext to the HTTPS port gets no answer.
    httplib::Client plain("127.0.0.1", port);
    plain.set_read_timeout(5);
    httplib::Result p = plain.Get("/api/jobs");
    EXPECT_TRUE(!p || p->status != 200);

    HttpServerOptions broken = DashboardOptions("127.0.0.1:0", tls, false);
    broken.tls_key_file = (dir_ / "ca.pem").string();
    HttpServer bad(*coordinator_, OpenAccess());
    EXPECT_THROW(bad.Start(broken), std::runtime_error);
}

TEST_F(HttpServerTest, MetricsArePrometheusText) {
    FarmMetrics metrics(*coordinator_);
    httplib::Client& c = Serve(OpenAccess(), [&] { return metrics.Scrape(); });
    Submit();
    httplib::Result r = c.Get("/metrics");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_EQ(r->get_header_value("Content-Type").rfind("text/plain; version=0.0.4", 0), 0u);
    EXPECT_NE(r->body.find("# TYPE "), std::string::npos) << r->body;
}

TEST_F(HttpServerTest, AnAddressInUseIsRefusedAndStopEndsServing) {
    Serve();
    HttpServer second(*coordinator_, OpenAccess());
    HttpServerOptions same;
    same.listen = "127.0.0.1:" + std::to_string(port_);
    EXPECT_THROW(second.Start(same), std::runtime_error) << "the port is taken";
    EXPECT_EQ(client_->Get("/api/jobs")->status, 200);
    http_->Stop();
    EXPECT_FALSE(client_->Get("/api/jobs")) << "stopped";
}

}  // namespace
}  // namespace tessera
