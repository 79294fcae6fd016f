// A farm behind TLS and tokens, as its users set it up: `tessera cert` makes the CA and
// the certificates, `tessera token` the tokens; the coordinator serves mutual TLS; the
// worker and the CLI connect with their own files. The image equals a local render, and
// a coordinator asked to listen off loopback without protection refuses to start.

#include <sys/stat.h>

#include "farm_harness.h"

namespace tessera {
namespace {

using namespace farm_testing;

class TlsFarmTest : public FarmHarness {
  protected:
    std::string P(const std::string& name) const { return (dir_ / name).string(); }
    void MakeCredentials() {
        const fs::path pki = dir_ / "pki";
        CliResult r = Cli({"cert", "ca", "--dir", pki.string()});
        ASSERT_EQ(r.code, 0) << r.err;
        r = Cli({"cert", "server", "--dir", pki.string(), "--host", "127.0.0.1"});
        ASSERT_EQ(r.code, 0) << r.err;
        r = Cli({"cert", "client", "--dir", pki.string(), "--name", "w1"});
        ASSERT_EQ(r.code, 0) << r.err;
        // A second run refuses to overwrite the CA key.
        r = Cli({"cert", "ca", "--dir", pki.string()});
        EXPECT_NE(r.code, 0);
        EXPECT_NE(r.err.find("exists; pass --force"), std::string::npos) << r.err;
        r = Cli({"token", "--role", "client", "--name", "alice", "--tokens", P("tokens"), "--out",
                 P("client.token")});
        ASSERT_EQ(r.code, 0) << r.err;
        r = Cli({"token", "--role", "worker", "--name", "render", "--tokens", P("tokens"), "--out",
                 P("worker.token")});
        ASSERT_EQ(r.code, 0) << r.err;
        struct stat st {};
        ASSERT_EQ(::stat(P("pki/ca.key").c_str(), &st), 0);
        EXPECT_EQ(st.st_mode & 0777, 0600u);
        ASSERT_EQ(::stat(P("worker.token").c_str(), &st), 0);
        EXPECT_EQ(st.st_mode & 0777, 0600u);
    }
    std::vector<std::string> ClientSecurity(const std::string& token_file) const {
        return {"--tls-ca", P("pki/ca.pem"), "--token-file", P(token_file)};
    }
};

TEST_F(TlsFarmTest, AFarmOverMutualTlsWithTokensRendersTheSameImage) {
    MakeCredentials();
    Process* coordinator = nullptr;
    const int port =
        StartCoordinator("state", 0, 0, &coordinator,
                         {"--tls-cert", P("pki/server.pem"), "--tls-key", P("pki/server.key"),
                          "--tls-client-ca", P("pki/ca.pem"), "--tokens", P("tokens")});
    ASSERT_GT(port, 0);
    std::vector<std::string> worker = WorkerArgv(port, "w1");
    worker = Concat(worker, {"--tls-ca", P("pki/ca.pem"), "--tls-cert", P("pki/w1.pem"),
                             "--tls-key", P("pki/w1.key"), "--token-file", P("worker.token")});
    Start(worker, "w1");

    const std::string address = "127.0.0.1:" + std::to_string(port);
    const std::vector<std::string> options = {"--width", "32", "--height",    "32",
                                              "--spp",   "4",  "--tile-size", "16"};
    // Without a token, and with the worker's token, the CLI is refused.
    CliResult refused = Cli({"status", "--coordinator", address, "--tls-ca", P("pki/ca.pem")});
    EXPECT_NE(refused.code, 0);
    EXPECT_NE(refused.err.find("UNAUTHENTICATED"), std::string::npos) << refused.err;
    refused = Cli(Concat({"status", "--coordinator", address}, ClientSecurity("worker.token")));
    EXPECT_NE(refused.code, 0);
    EXPECT_NE(refused.err.find("PERMISSION_DENIED"), std::string::npos) << refused.err;

    CliResult submitted = Cli(Concat({"submit", kCornell, "--coordinator", address, "--watch"},
                                     Concat(ClientSecurity("client.token"), options)),
                              300s);
    ASSERT_EQ(submitted.code, 0) << submitted.err;
    const std::string job = Trim(submitted.out.substr(0, submitted.out.find('\n')));
    CliResult fetched = Cli(Concat({"fetch", job, "-o", P("fetched"), "--coordinator", address},
                                   ClientSecurity("client.token")));
    ASSERT_EQ(fetched.code, 0) << fetched.err;
    fs::path frame;
    for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir_ / "fetched"))
        if (e.path().extension() == ".exr") frame = e.path();
    ASSERT_FALSE(frame.empty());
    ExpectSameImage(RenderLocal(options), frame);

    CliResult workers =
        Cli(Concat({"workers", "--coordinator", address}, ClientSecurity("client.token")));
    ASSERT_EQ(workers.code, 0) << workers.err;
    EXPECT_NE(workers.out.find("w1"), std::string::npos) << workers.out;
    EXPECT_NE(workers.out.find("idle"), std::string::npos) << workers.out;

    // The coordinator's log names who submitted, and from where.
    coordinator->Kill(SIGTERM);
    coordinator->Wait(60s);
    std::string log;
    for (const fs::directory_entry& e : fs::directory_iterator(dir_))
        if (e.path().filename().string().rfind("state-", 0) == 0) log += ReadFile(e.path());
    EXPECT_NE(log.find("submitted by client 'alice' from ipv4:127.0.0.1:"), std::string::npos)
        << log;
    EXPECT_NE(log.find("registration of worker 'w1' by worker 'render' from ipv4:127.0.0.1:"),
              std::string::npos);
    EXPECT_NE(log.find("mutual TLS"), std::string::npos);
}

TEST_F(TlsFarmTest, OffLoopbackWithoutTlsAndTokensTheCoordinatorRefusesToStart) {
    std::vector<std::string> argv = {TESSERA_COORDINATOR, "--listen", "0.0.0.0:0", "--state",
                                     P("state"),          "--output", P("frames")};
    Process& refused = Start(argv, "refused");
    EXPECT_EQ(refused.Wait(60s), 1);
    const std::string log = ReadFile(dir_ / "refused.log");
    EXPECT_NE(log.find("refusing to listen on 0.0.0.0:0 without TLS"), std::string::npos) << log;

    // --insecure starts it, with a warning.
    argv.push_back("--insecure");
    argv.push_back("--port-file");
    argv.push_back(P("insecure.port"));
    Process& insecure = Start(argv, "insecure");
    auto deadline = Clock::now() + 120s;
    while (Clock::now() < deadline && ReadFile(dir_ / "insecure.port").empty() &&
           insecure.Running())
        std::this_thread::sleep_for(10ms);
    EXPECT_FALSE(ReadFile(dir_ / "insecure.port").empty()) << ReadFile(dir_ / "insecure.log");
    EXPECT_NE(ReadFile(dir_ / "insecure.log").find("--insecure: listening on 0.0.0.0:0"),
              std::string::npos);
}

}  // namespace
}  // namespace tessera
