// Who may call the coordinator: token files, roles, TLS and mutual TLS, the refusal to
// listen off loopback unprotected, and per-token limits. The services run in a real gRPC
// server on 127.0.0.1 with certificates made by the farm's own CA code.

#include "auth.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "blob_client.h"
#include "certificates.h"
#include "clock.h"
#include "coordinator.h"
#include "coordinator_fixtures.h"
#include "security.h"
#include "services.h"
#include "sha256.h"
#include "tessera/v1/tessera.grpc.pb.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

using test::kClientToken;
using test::kWorkerToken;

const std::string kScene =
    test::SphereUnderSkyScene({.width = 16, .height = 16, .spp = 2, .max_depth = 2});

std::string ParseError(const std::string& text) {
    try {
        Authenticator::FromText(text, "tokens");
    } catch (const std::exception& e) {
        return e.what();
    }
    return "";
}

TEST(TokenFile, ParsesRolesNamesHashesAndLimits) {
    const std::string hashed = Sha256Hex("a-third-token-0123456789");
    Authenticator auth = Authenticator::FromText(
        "# role name token\n"
        "client alice " +
            kClientToken +
            " max_spp=64 max_priority=5\n"
            "\n"
            "worker render " +
            kWorkerToken +
            "   # a comment\n"
            "client bob sha256:" +
            hashed + "\n",
        "tokens");
    EXPECT_TRUE(auth.Enabled());
    EXPECT_EQ(auth.Count(Role::kClient), 2);
    EXPECT_EQ(auth.Count(Role::kWorker), 1);
    EXPECT_FALSE(Authenticator().Enabled());
}

TEST(TokenFile, MalformedLinesNameTheFileAndLine) {
    EXPECT_EQ(ParseError("client alice " + kClientToken + "\nadmin x " + kWorkerToken),
              "tokens:2: the role is 'client' or 'worker', not 'admin'");
    EXPECT_EQ(ParseError("client alice"), "tokens:1: expected 'ROLE NAME TOKEN [limits]'");
    EXPECT_NE(ParseError("client alice short").find("tokens:1: the token is shorter than 16"),
              std::string::npos);
    EXPECT_EQ(ParseError("client a " + kClientToken + "\nworker b " + kClientToken),
              "tokens:2: the same token appears twice");
    EXPECT_NE(ParseError("client a " + kClientToken + " max_cores=3").find("unknown limit"),
              std::string::npos);
    EXPECT_NE(ParseError("client a " + kClientToken + " max_spp=-3").find("not a whole number"),
              std::string::npos);
    EXPECT_EQ(ParseError("worker a " + kWorkerToken + " max_spp=3"),
              "tokens:1: limits apply to client tokens only");
    EXPECT_NE(ParseError("client a sha256:abc").find("64 hex digits"), std::string::npos);
}

TEST(ListenSecurity, LoopbackAddresses) {
    EXPECT_TRUE(IsLoopbackAddress("127.0.0.1:50051"));
    EXPECT_TRUE(IsLoopbackAddress("127.1.2.3:0"));
    EXPECT_TRUE(IsLoopbackAddress("localhost:50051"));
    EXPECT_TRUE(IsLoopbackAddress("[::1]:50051"));
    EXPECT_TRUE(IsLoopbackAddress("unix:/run/tessera.sock"));
    EXPECT_FALSE(IsLoopbackAddress("0.0.0.0:50051"));
    EXPECT_FALSE(IsLoopbackAddress("[::]:50051"));
    EXPECT_FALSE(IsLoopbackAddress("10.0.0.7:50051"));
    EXPECT_FALSE(IsLoopbackAddress("farm.example.com:50051"));
    EXPECT_FALSE(IsLoopbackAddress("127.0.0.1.example.com:1"));
}

TEST(ListenSecurity, OffLoopbackNeedsTlsAndTokensUnlessInsecure) {
    ListenSecurity plain;
    EXPECT_NO_THROW(CheckListenSecurity("127.0.0.1:0", plain, false));
    try {
        CheckListenSecurity("0.0.0.0:50051", plain, false);
        FAIL() << "listening on 0.0.0.0 without TLS was allowed";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("TLS (--tls-cert, --tls-key) and tokens"),
                  std::string::npos)
            << e.what();
    }
    ListenSecurity tls;
    tls.tls_cert_file = "server.pem";
    tls.tls_key_file = "server.key";
    EXPECT_THROW(CheckListenSecurity("0.0.0.0:50051", tls, false), std::runtime_error);
    EXPECT_NO_THROW(CheckListenSecurity("0.0.0.0:50051", tls, true));
    EXPECT_THROW(CheckListenSecurity("0.0.0.0:50051", plain, true), std::runtime_error);
    ListenSecurity insecure;
    insecure.insecure = true;
    EXPECT_NO_THROW(CheckListenSecurity("0.0.0.0:50051", insecure, false));
    ListenSecurity half;
    half.tls_cert_file = "server.pem";
    EXPECT_THROW(CheckListenSecurity("127.0.0.1:0", half, false), std::runtime_error);
}

TEST(Certificates, TheCaSignsServerAndClientCertificates) {
    KeyAndCertificate ca = MakeCertificateAuthority("test CA", 1);
    EXPECT_NE(ca.certificate_pem.find("BEGIN CERTIFICATE"), std::string::npos);
    EXPECT_NE(ca.key_pem.find("PRIVATE KEY"), std::string::npos);
    KeyAndCertificate server = MakeCertificate(ca, "farm", {"localhost", "10.1.2.3", "::1"}, 1);
    EXPECT_NE(server.certificate_pem, ca.certificate_pem);
    EXPECT_THROW(MakeCertificate(ca, "x", {"bad name,DNS:evil"}, 1), std::runtime_error);
    KeyAndCertificate other = MakeCertificateAuthority("other", 1);
    KeyAndCertificate mixed{other.key_pem, ca.certificate_pem};
    EXPECT_THROW(MakeCertificate(mixed, "x", {}, 1), std::runtime_error);
    EXPECT_EQ(NewToken().size(), 64u);
    EXPECT_NE(NewToken(), NewToken());
}

// A coordinator behind a real gRPC server on 127.0.0.1, TLS and tokens configurable.
class AuthServerTest : public ::testing::Test {
  protected:
    void SetUp() override {
        spdlog::set_level(spdlog::level::warn);
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_auth_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        ca_ = MakeCertificateAuthority("farm CA", 1);
        Write("ca.pem", ca_.certificate_pem);
        KeyAndCertificate server = MakeCertificate(ca_, "localhost", {"localhost", "127.0.0.1"}, 1);
        Write("server.pem", server.certificate_pem);
        Write("server.key", server.key_pem);
        KeyAndCertificate worker = MakeCertificate(ca_, "worker-1", {}, 1);
        Write("worker.pem", worker.certificate_pem);
        Write("worker.key", worker.key_pem);
        KeyAndCertificate stranger_ca = MakeCertificateAuthority("stranger CA", 1);
        Write("stranger-ca.pem", stranger_ca.certificate_pem);
        KeyAndCertificate stranger = MakeCertificate(stranger_ca, "worker-x", {}, 1);
        Write("stranger.pem", stranger.certificate_pem);
        Write("stranger.key", stranger.key_pem);

        options_.state_dir = (dir_ / "state").string();
        options_.output_dir = (dir_ / "out").string();
        options_.limits.max_spp = 1000;
    }
    void TearDown() override {
        if (server_) {
            coordinator_->StopWaiting();
            server_->Shutdown(std::chrono::system_clock::now());
        }
        server_.reset();
        farm_.reset();
        workers_.reset();
        blobs_.reset();
        coordinator_.reset();
        fs::remove_all(dir_);
    }
    std::string Path(const std::string& name) const { return (dir_ / name).string(); }
    void Write(const std::string& name, const std::string& text) {
        std::ofstream(dir_ / name, std::ios::binary) << text;
    }

    void Start(bool tls, bool mutual,
               const std::string& tokens = "client alice " + kClientToken +
                                           " max_spp=8 max_priority=5\nworker render " +
                                           kWorkerToken + "\n") {
        auth_ = Authenticator::FromText(tokens, "tokens");
        ListenSecurity security;
        if (tls) {
            security.tls_cert_file = Path("server.pem");
            security.tls_key_file = Path("server.key");
            if (mutual) security.tls_client_ca_file = Path("ca.pem");
        }
        auth_.RequireWorkerCertificates(mutual);
        coordinator_ = std::make_unique<Coordinator>(options_, clock_);
        coordinator_->Start();
        farm_ = MakeFarmService(*coordinator_, auth_);
        workers_ = MakeWorkersService(*coordinator_, auth_);
        blobs_ = MakeBlobStoreService(*coordinator_, auth_);
        grpc::ServerBuilder builder;
        builder.AddListeningPort("127.0.0.1:0", MakeServerCredentials(security), &port_);
        builder.RegisterService(farm_.get());
        builder.RegisterService(workers_.get());
        builder.RegisterService(blobs_.get());
        server_ = builder.BuildAndStart();
        ASSERT_TRUE(server_);
        ASSERT_NE(port_, 0);
    }

    struct Stubs {
        std::unique_ptr<v1::Farm::Stub> farm;
        std::unique_ptr<v1::Workers::Stub> workers;
        std::unique_ptr<v1::BlobStore::Stub> blobs;
    };
    Stubs Connect(const ClientSecurity& security) {
        auto channel =
            MakeChannel("127.0.0.1:" + std::to_string(port_), security, grpc::ChannelArguments());
        return {v1::Farm::NewStub(channel), v1::Workers::NewStub(channel),
                v1::BlobStore::NewStub(channel)};
    }
    ClientSecurity Tls(const std::string& token) const {
        ClientSecurity s;
        s.ca_file = Path("ca.pem");
        s.token = token;
        return s;
    }

    static grpc::StatusCode ListJobs(Stubs& s, std::string* message = nullptr) {
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
        v1::ListJobsResponse resp;
        grpc::Status status = s.farm->ListJobs(&ctx, v1::ListJobsRequest(), &resp);
        if (message) *message = status.error_message();
        return status.error_code();
    }
    static grpc::StatusCode Register(Stubs& s) {
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
        v1::RegisterRequest req;
        req.set_name("w1");
        req.set_threads(1);
        v1::RegisterResponse resp;
        return s.workers->Register(&ctx, req, &resp).error_code();
    }
    static grpc::StatusCode GetBlob(Stubs& s) {
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
        v1::GetBlobRequest req;
        req.set_hash(Sha256Hex("x"));
        auto reader = s.blobs->GetBlob(&ctx, req);
        v1::BlobChunk chunk;
        while (reader->Read(&chunk)) {
        }
        return reader->Finish().error_code();
    }
    static grpc::StatusCode Download(Stubs& s) {
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
        v1::DownloadFrameRequest req;
        req.set_job_id("1");
        auto reader = s.farm->DownloadFrame(&ctx, req);
        v1::FileChunk chunk;
        while (reader->Read(&chunk)) {
        }
        return reader->Finish().error_code();
    }
    static grpc::StatusCode Submit(Stubs& s, int spp, int priority, std::string* message) {
        std::string hash;
        try {
            hash = UploadBlob(*s.blobs, kScene);
        } catch (const std::exception& e) {
            *message = e.what();
            return grpc::StatusCode::UNKNOWN;
        }
        grpc::ClientContext ctx;
        ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
        v1::SubmitJobRequest req;
        v1::JobSpec* spec = req.mutable_spec();
        spec->set_name("limits");
        spec->set_scene_path("scene.json");
        spec->set_priority(priority);
        spec->mutable_options()->set_spp(spp);
        v1::BundleFile* f = spec->add_files();
        f->set_path("scene.json");
        f->set_hash(hash);
        f->set_size(std::string(kScene).size());
        v1::SubmitJobResponse resp;
        grpc::Status status = s.farm->SubmitJob(&ctx, req, &resp);
        *message = status.error_message();
        return status.error_code();
    }

    fs::path dir_;
    KeyAndCertificate ca_;
    CoordinatorOptions options_;
    SystemClock clock_;
    Authenticator auth_;
    std::unique_ptr<Coordinator> coordinator_;
    std::unique_ptr<grpc::Service> farm_, workers_, blobs_;
    std::unique_ptr<grpc::Server> server_;
    int port_ = 0;
};

TEST_F(AuthServerTest, EachRoleMakesOnlyItsOwnCalls) {
    Start(/*tls=*/true, /*mutual=*/false);
    Stubs none = Connect(Tls(""));
    Stubs wrong = Connect(Tls("not-a-token-of-this-farm-000"));
    Stubs client = Connect(Tls(kClientToken));
    Stubs worker = Connect(Tls(kWorkerToken));

    std::string message;
    EXPECT_EQ(ListJobs(none, &message), grpc::StatusCode::UNAUTHENTICATED);
    EXPECT_NE(message.find("needs a token"), std::string::npos) << message;
    EXPECT_EQ(ListJobs(wrong), grpc::StatusCode::UNAUTHENTICATED);
    EXPECT_EQ(Register(none), grpc::StatusCode::UNAUTHENTICATED);
    EXPECT_EQ(GetBlob(none), grpc::StatusCode::UNAUTHENTICATED);

    // A worker token cannot submit, list, cancel or download.
    EXPECT_EQ(ListJobs(worker, &message), grpc::StatusCode::PERMISSION_DENIED);
    EXPECT_NE(message.find("a worker token ('render') may not make client calls"),
              std::string::npos)
        << message;
    EXPECT_EQ(Submit(worker, 2, 0, &message), grpc::StatusCode::PERMISSION_DENIED) << message;
    EXPECT_EQ(Download(worker), grpc::StatusCode::PERMISSION_DENIED);
    {
        grpc::ClientContext ctx;
        v1::CancelJobRequest req;
        req.set_job_id("1");
        v1::CancelJobResponse resp;
        EXPECT_EQ(worker.farm->CancelJob(&ctx, req, &resp).error_code(),
                  grpc::StatusCode::PERMISSION_DENIED);
    }
    // A client token cannot register, lease or read blobs.
    EXPECT_EQ(Register(client), grpc::StatusCode::PERMISSION_DENIED);
    EXPECT_EQ(GetBlob(client), grpc::StatusCode::PERMISSION_DENIED);
    {
        grpc::ClientContext ctx;
        v1::LeaseTaskRequest req;
        req.set_worker_id("1");
        v1::LeaseTaskResponse resp;
        EXPECT_EQ(client.workers->LeaseTask(&ctx, req, &resp).error_code(),
                  grpc::StatusCode::PERMISSION_DENIED);
    }
    {
        grpc::ClientContext ctx;
        v1::CompleteTaskRequest req;
        v1::CompleteTaskResponse resp;
        EXPECT_EQ(client.workers->CompleteTask(&ctx, req, &resp).error_code(),
                  grpc::StatusCode::PERMISSION_DENIED);
    }

    // Each role's own calls pass.
    EXPECT_EQ(ListJobs(client), grpc::StatusCode::OK);
    EXPECT_EQ(Register(worker), grpc::StatusCode::OK);
    EXPECT_EQ(GetBlob(worker), grpc::StatusCode::NOT_FOUND);  // past the check: no such blob
    EXPECT_EQ(Submit(client, 2, 0, &message), grpc::StatusCode::OK) << message;
}

TEST_F(AuthServerTest, AClientThatDoesNotTrustTheServerCertificateIsRefused) {
    Start(/*tls=*/true, /*mutual=*/false);
    ClientSecurity stranger = Tls(kClientToken);
    stranger.ca_file = Path("stranger-ca.pem");
    Stubs wrong_ca = Connect(stranger);
    std::string message;
    EXPECT_EQ(ListJobs(wrong_ca, &message), grpc::StatusCode::UNAVAILABLE) << message;
    ClientSecurity plain;
    plain.token = kClientToken;
    Stubs plaintext = Connect(plain);
    EXPECT_EQ(ListJobs(plaintext), grpc::StatusCode::UNAVAILABLE);
    Stubs good = Connect(Tls(kClientToken));
    EXPECT_EQ(ListJobs(good), grpc::StatusCode::OK);
}

TEST_F(AuthServerTest, MutualTlsWorkersNeedACertificateOfTheFarmsCa) {
    Start(/*tls=*/true, /*mutual=*/true);
    Stubs no_cert = Connect(Tls(kWorkerToken));
    EXPECT_EQ(Register(no_cert), grpc::StatusCode::UNAUTHENTICATED);
    ClientSecurity with_cert = Tls(kWorkerToken);
    with_cert.cert_file = Path("worker.pem");
    with_cert.key_file = Path("worker.key");
    Stubs good = Connect(with_cert);
    EXPECT_EQ(Register(good), grpc::StatusCode::OK);
    ClientSecurity foreign = Tls(kWorkerToken);
    foreign.cert_file = Path("stranger.pem");
    foreign.key_file = Path("stranger.key");
    Stubs stranger = Connect(foreign);
    EXPECT_NE(Register(stranger), grpc::StatusCode::OK);
    // Clients need no certificate.
    Stubs client = Connect(Tls(kClientToken));
    EXPECT_EQ(ListJobs(client), grpc::StatusCode::OK);
}

TEST_F(AuthServerTest, ATokensLimitsTightenTheCoordinators) {
    Start(/*tls=*/false, /*mutual=*/false);
    ClientSecurity plain;
    plain.token = kClientToken;
    Stubs client = Connect(plain);
    std::string message;
    EXPECT_EQ(Submit(client, 16, 0, &message), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(message.find("16 spp is over the limit of token 'alice', 8"), std::string::npos)
        << message;
    EXPECT_EQ(Submit(client, 4, 6, &message), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(message.find("priority 6 is over the limit of token 'alice', 5"), std::string::npos)
        << message;
    EXPECT_EQ(Submit(client, 8, 5, &message), grpc::StatusCode::OK) << message;
}

TEST_F(AuthServerTest, WithoutTokensEveryCallerIsAcceptedOnLoopback) {
    Start(/*tls=*/false, /*mutual=*/false, /*tokens=*/"");
    Stubs anyone = Connect(ClientSecurity());
    EXPECT_EQ(ListJobs(anyone), grpc::StatusCode::OK);
    EXPECT_EQ(Register(anyone), grpc::StatusCode::OK);
}

}  // namespace
}  // namespace tessera
