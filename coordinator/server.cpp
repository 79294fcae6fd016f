#include "server.h"

#include <grpcpp/ext/health_check_service_server_builder_option.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "services.h"

namespace tessera {

namespace {

constexpr int kMaxMessageBytes = 16 << 20;
constexpr auto kShutdownGrace = std::chrono::seconds(5);

sigset_t ShutdownSignals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGINT);
    return set;
}

// Written to a temporary name, flushed and renamed: a reader never sees a partial port.
void WritePortFile(const std::string& path, int port) {
    const std::string temp = path + ".tmp." + std::to_string(::getpid());
    {
        std::ofstream out(temp, std::ios::trunc);
        out << port << "\n";
        out.flush();
        if (!out) throw std::runtime_error("cannot write " + temp);
    }
    std::filesystem::rename(temp, path);
}

}  // namespace

void BlockShutdownSignals() {
    // A shell starts background processes with SIGINT ignored, and an ignored signal is
    // discarded even while blocked: restore the default so that sigwait() receives it.
    ::signal(SIGINT, SIG_DFL);
    ::signal(SIGTERM, SIG_DFL);
    sigset_t set = ShutdownSignals();
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

int RunServer(const ServerOptions& options) {
    Authenticator auth;
    std::shared_ptr<grpc::ServerCredentials> credentials;
    try {
        if (!options.security.tokens_file.empty())
            auth = Authenticator::FromFile(options.security.tokens_file);
        CheckListenSecurity(options.listen, options.security, auth.Enabled());
        credentials = MakeServerCredentials(options.security);
        auth.RequireWorkerCertificates(!options.security.tls_client_ca_file.empty());
    } catch (const std::exception& e) {
        spdlog::critical("{}", e.what());
        return 1;
    }
    if (auth.Enabled())
        spdlog::info("tokens: {} client, {} worker (from {})", auth.Count(Role::kClient),
                     auth.Count(Role::kWorker), options.security.tokens_file);
    else
        spdlog::info("no tokens: every caller on {} may submit and render", options.listen);
    SystemClock clock;
    std::unique_ptr<Coordinator> coordinator;
    try {
        coordinator = std::make_unique<Coordinator>(options.coordinator, clock);
    } catch (const std::exception& e) {
        spdlog::critical("cannot open the state in {}: {}", options.coordinator.state_dir,
                         e.what());
        return 1;
    }

    std::unique_ptr<grpc::Service> farm = MakeFarmService(*coordinator, auth);
    std::unique_ptr<grpc::Service> workers = MakeWorkersService(*coordinator, auth);
    std::unique_ptr<grpc::Service> blobs = MakeBlobStoreService(*coordinator, auth);
    grpc::EnableDefaultHealthCheckService(true);
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort(options.listen, credentials, &port);
    builder.SetMaxReceiveMessageSize(kMaxMessageBytes);
    builder.SetMaxSendMessageSize(kMaxMessageBytes);
    builder.RegisterService(farm.get());
    builder.RegisterService(workers.get());
    builder.RegisterService(blobs.get());
    coordinator->Start();
    std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
    if (!server || port == 0) {
        spdlog::critical("cannot listen on {} (address in use, or not a valid host:port)",
                         options.listen);
        if (server) server->Shutdown();
        coordinator->StopWaiting();
        coordinator->Stop();
        return 1;
    }
    if (grpc::HealthCheckServiceInterface* health = server->GetHealthCheckService())
        health->SetServingStatus(true);
    spdlog::info("tessera-coordinator listening on {} (port {}, {}); state {}, output {}",
                 options.listen, port,
                 options.security.tls_cert_file.empty()
                     ? "plaintext"
                     : (options.security.tls_client_ca_file.empty() ? "TLS" : "mutual TLS"),
                 options.coordinator.state_dir, options.coordinator.output_dir);
    if (!options.port_file.empty()) {
        try {
            WritePortFile(options.port_file, port);
        } catch (const std::exception& e) {
            spdlog::critical("cannot write the port file: {}", e.what());
            server->Shutdown();
            coordinator->StopWaiting();
            coordinator->Stop();
            return 1;
        }
    }

    sigset_t set = ShutdownSignals();
    int signal = 0;
    sigwait(&set, &signal);
    spdlog::info("received {}; shutting down", signal == SIGTERM ? "SIGTERM" : "SIGINT");
    if (grpc::HealthCheckServiceInterface* health = server->GetHealthCheckService())
        health->SetServingStatus(false);
    coordinator->StopWaiting();  // answer long polls and watches, so the server can drain
    server->Shutdown(std::chrono::system_clock::now() + kShutdownGrace);
    coordinator->Stop();  // finishes the frame being written
    server.reset();
    farm.reset();
    coordinator.reset();  // closes the database
    spdlog::info("tessera-coordinator stopped");
    return 0;
}

}  // namespace tessera
