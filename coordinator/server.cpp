#include "server.h"

#include <grpcpp/ext/health_check_service_server_builder_option.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <netdb.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>

#include "http_server.h"
#include "metrics.h"
#include "services.h"
#include "tessera/v1/tessera.grpc.pb.h"

namespace tessera {

bool SplitHostPort(const std::string& listen, std::string* host, std::string* port) {
    if (listen.find('/') != std::string::npos || listen.rfind("unix", 0) == 0) return false;
    const size_t colon = listen.rfind(':');
    if (colon == std::string::npos) return false;
    *host = listen.substr(0, colon);
    *port = listen.substr(colon + 1);
    if (host->size() >= 2 && host->front() == '[' && host->back() == ']')
        *host = host->substr(1, host->size() - 2);
    return true;
}

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

// Why the coordinator cannot listen on `listen`, found by binding its address as gRPC
// does (SO_REUSEADDR, no SO_REUSEPORT), or "" when nothing stands in the way. gRPC
// itself only says that it failed.
std::string ListenProblem(const std::string& listen) {
    std::string host, port;
    if (!SplitHostPort(listen, &host, &port) || port == "0") return {};
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE;
    addrinfo* found = nullptr;
    if (int rc = getaddrinfo(host.empty() ? nullptr : host.c_str(), port.c_str(), &hints, &found);
        rc != 0)
        return fmt::format("cannot listen on {}: {}", listen, gai_strerror(rc));
    const std::string where = host.empty() ? "every address" : host;
    std::string problem;
    for (addrinfo* a = found; a && problem.empty(); a = a->ai_next) {
        const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
        if (fd < 0) continue;
        const int one = 1;
        ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        const int error = ::bind(fd, a->ai_addr, a->ai_addrlen) == 0 ? 0 : errno;
        ::close(fd);
        if (error == EADDRINUSE)
            problem = fmt::format("port {} on {} is in use by another process", port, where);
        else if (error == EACCES)
            problem = fmt::format("cannot listen on {}: permission denied", listen);
        else if (error == EADDRNOTAVAIL)
            problem = fmt::format("cannot listen on {}: {} is not an address of this machine",
                                  listen, host);
    }
    freeaddrinfo(found);
    return problem;
}

// The services health checks may ask about by name, besides "" (the whole server).
constexpr const char* kServiceNames[] = {v1::Farm::service_full_name(),
                                         v1::Workers::service_full_name(),
                                         v1::BlobStore::service_full_name()};

void SetServingStatus(grpc::Server& server, bool serving) {
    grpc::HealthCheckServiceInterface* health = server.GetHealthCheckService();
    if (!health) return;
    health->SetServingStatus(serving);  // "" and every name set so far
    for (const char* name : kServiceNames) health->SetServingStatus(name, serving);
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
    std::optional<HttpServerOptions> dashboard;
    try {
        if (!options.security.tokens_file.empty())
            auth = Authenticator::FromFile(options.security.tokens_file);
        CheckListenSecurity(options.listen, options.security, auth.Enabled());
        if (!options.http_listen.empty())
            dashboard = DashboardOptions(options.http_listen, options.security, auth.Enabled());
        credentials = MakeServerCredentials(options.security);
        auth.RequireWorkerCertificates(!options.security.tls_client_ca_file.empty());
    } catch (const std::exception& e) {
        spdlog::critical("{}", e.what());
        return 1;
    }
    // Before the state is opened: a coordinator started twice must not touch it.
    for (const std::string& listen : {options.listen, options.http_listen}) {
        if (std::string problem = ListenProblem(listen); !problem.empty()) {
            spdlog::critical("{}{}", problem, listen == options.listen ? "" : " (--http-listen)");
            return 1;
        }
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
    // Lets tools (grpcurl, grpc_cli, Postman) list and call the services without the .proto.
    grpc::reflection::InitProtoReflectionServerBuilderPlugin();
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort(options.listen, credentials, &port);
    // gRPC sets SO_REUSEPORT by default, so that a second coordinator on the same port
    // would share it with the first, each answering some of the calls.
    builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
    builder.SetMaxReceiveMessageSize(kMaxMessageBytes);
    builder.SetMaxSendMessageSize(kMaxMessageBytes);
    builder.RegisterService(farm.get());
    builder.RegisterService(workers.get());
    builder.RegisterService(blobs.get());
    coordinator->Start();
    std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
    std::unique_ptr<FarmMetrics> metrics;
    std::unique_ptr<HttpServer> http;
    // A start that fails after the coordinator started: everything stops in order.
    auto give_up = [&](const std::string& problem) {
        spdlog::critical("{}", problem);
        if (http) http->Stop();
        if (server) server->Shutdown();
        coordinator->StopWaiting();
        coordinator->Stop();
        return 1;
    };
    if (!server || port == 0) {
        std::string problem = ListenProblem(options.listen);
        return give_up(problem.empty() ? "cannot listen on " + options.listen : problem);
    }
    SetServingStatus(*server, true);
    spdlog::info("tessera-coordinator listening on {} (port {}, {}); state {}, output {}",
                 options.listen, port,
                 options.security.tls_cert_file.empty()
                     ? "plaintext"
                     : (options.security.tls_client_ca_file.empty() ? "TLS" : "mutual TLS"),
                 options.coordinator.state_dir, options.coordinator.output_dir);
    if (dashboard) {
        try {
            metrics = std::make_unique<FarmMetrics>(*coordinator);
            http = std::make_unique<HttpServer>(*coordinator, auth,
                                                [m = metrics.get()] { return m->Scrape(); });
            const int http_port = http->Start(*dashboard);
            spdlog::info("dashboard at {} ({})", http->Url(),
                         auth.Enabled() ? "client tokens only" : "no tokens: open to its callers");
            if (!options.http_port_file.empty()) WritePortFile(options.http_port_file, http_port);
        } catch (const std::exception& e) {
            return give_up(std::string("dashboard: ") + e.what());
        }
    }
    if (!options.port_file.empty()) {
        try {
            WritePortFile(options.port_file, port);
        } catch (const std::exception& e) {
            return give_up(std::string("cannot write the port file: ") + e.what());
        }
    }

    sigset_t set = ShutdownSignals();
    int signal = 0;
    sigwait(&set, &signal);
    spdlog::info("received {}; shutting down", signal == SIGTERM ? "SIGTERM" : "SIGINT");
    SetServingStatus(*server, false);
    if (http) http->Stop();      // its requests call the coordinator
    coordinator->StopWaiting();  // answer long polls and watches, so the server can drain
    server->Shutdown(std::chrono::system_clock::now() + kShutdownGrace);
    coordinator->Stop();  // finishes the frame being written
    server.reset();
    http.reset();
    metrics.reset();
    farm.reset();
    coordinator.reset();  // closes the database
    spdlog::info("tessera-coordinator stopped");
    return 0;
}

}  // namespace tessera
