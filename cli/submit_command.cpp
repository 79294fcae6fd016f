// `tessera submit SCENE.json --coordinator HOST:PORT`: sends a scene bundle and a job.

#include <cstdio>
#include <memory>

#include "bundle.h"
#include "farm_commands.h"
#include "job_options.h"

namespace tessera {
namespace {

struct SubmitOptions {
    std::string scene;
    CoordinatorEndpoint coordinator;
    JobOptions job;
    bool watch = false;
    bool quiet = false;
};

void RunSubmit(const SubmitOptions& o, const CLI::App& cmd) {
    v1::JobSpec spec = o.job.Spec(cmd, o.scene);
    std::vector<BundleEntry> bundle = CollectBundle(o.scene);
    FarmClient client(o.coordinator);
    std::string job_id = client.Submit(bundle, spec);
    // Only the id on stdout, so that `job=$(tessera submit ...)` works.
    std::printf("%s\n", job_id.c_str());
    std::fflush(stdout);
    if (!o.watch) return;
    FollowOptions follow;
    follow.quiet = o.quiet;
    follow.reconnect_seconds = 30;
    if (int code = FollowJob(client, job_id, follow); code != 0) throw CLI::RuntimeError(code);
}

}  // namespace

void AddSubmitCommand(CLI::App& app) {
    auto o = std::make_shared<SubmitOptions>();
    CLI::App* cmd = app.add_subcommand(
        "submit", "Submit a scene to a farm; prints the job id (its files are uploaded)");
    cmd->add_option("scene", o->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
    AddCoordinatorOption(*cmd, o->coordinator);
    o->job.AddTo(*cmd);
    cmd->add_flag("--watch", o->watch, "Then follow the job like `tessera watch`");
    cmd->add_flag("-q,--quiet", o->quiet, "No progress display (with --watch)");
    cmd->callback([o, cmd] { RunSubmit(*o, *cmd); });
}

}  // namespace tessera
