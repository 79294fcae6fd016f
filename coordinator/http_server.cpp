#include "http_server.h"

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>

#include <atomic>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <thread>

#include "dashboard_assets.h"
#include "dashboard_json.h"
#include "errors.h"
#include "preview.h"
#include "security.h"
#include "server.h"

namespace tessera {

using nlohmann::json;

namespace {

constexpr const char* kTokenCookie = "tessera_token";
constexpr const char* kJsonType = "application/json";
constexpr int kDefaultLogLimit = 200;
constexpr int kMaxLogLimit = 10000;
constexpr size_t kMaxRequestBytes = 64 << 10;
constexpr time_t kKeepAliveSeconds = 2;  // also how long Stop() may wait for idle connections

// A path parameter: a job id, a frame, a worker's name.
const std::string kSegment = "([^/]+)";

int64_t NowUnixMs() {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

int HttpStatus(ErrorCode code) {
    switch (code) {
        case ErrorCode::kInvalidArgument:
            return 400;
        case ErrorCode::kNotFound:
            return 404;
        case ErrorCode::kFailedPrecondition:
            return 409;
        case ErrorCode::kResourceExhausted:
        case ErrorCode::kUnavailable:
            return 503;
        case ErrorCode::kDataLoss:
        case ErrorCode::kInternal:
            return 500;
    }
    return 500;
}

// Never throws: log messages and worker names may hold bytes that are not UTF-8.
std::string Dump(const json& value) {
    return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

void SendJson(httplib::Response& res, int status, const json& body) {
    res.status = status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(Dump(body), kJsonType);
}

void SendError(httplib::Response& res, int status, const std::string& message) {
    SendJson(res, status, json{{"error", message}});
}

// Runs a handler, answering an exception with its status and {"error": message}.
void Guarded(httplib::Response& res, const std::function<void()>& handler) {
    try {
        handler();
    } catch (const CoordinatorError& e) {
        SendError(res, HttpStatus(e.Code()), e.what());
    } catch (const json::exception& e) {
        SendError(res, 400, std::string("malformed request: ") + e.what());
    } catch (const std::exception& e) {
        spdlog::error("dashboard: internal error: {}", e.what());
        SendError(res, 500, e.what());
    } catch (...) {
        spdlog::error("dashboard: internal error of unknown type");
        SendError(res, 500, "internal error");
    }
}

// A job id from a path, as the coordinator writes it ("job-000001" is "job-1"): one that
// cannot name a job names no job (404, not 400).
std::string JobIdOf(const std::string& text) {
    try {
        return FormatJobId(ParseJobId(text));
    } catch (const CoordinatorError&) {
        ThrowError(ErrorCode::kNotFound, fmt::format("no job '{}'", text));
    }
}

// A whole number in [min, max], or INVALID_ARGUMENT naming `what`.
int64_t ParseInteger(const std::string& text, const std::string& what, int64_t min, int64_t max) {
    int64_t value = 0;
    const char* end = text.data() + text.size();
    auto [at, error] = std::from_chars(text.data(), end, value);
    if (error != std::errc() || at != end || value < min || value > max)
        ThrowError(
            ErrorCode::kInvalidArgument,
            fmt::format("{} must be a whole number from {} to {}, not '{}'", what, min, max, text));
    return value;
}

// Cookie values carry the token percent-encoded: a token may hold ';' or ','.
std::string PercentEncode(const std::string& text) {
    std::string out;
    for (unsigned char c : text) {
        if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~')
            out += static_cast<char>(c);
        else
            out += fmt::format("%{:02X}", c);
    }
    return out;
}

std::string PercentDecode(const std::string& text) {
    std::string out;
    for (size_t i = 0; i < text.size(); ++i) {
        unsigned value = 0;
        if (text[i] == '%' && i + 2 < text.size() &&
            std::from_chars(text.data() + i + 1, text.data() + i + 3, value, 16).ptr ==
                text.data() + i + 3) {
            out += static_cast<char>(value);
            i += 2;
        } else {
            out += text[i];
        }
    }
    return out;
}

// The value of cookie `name` in the request's Cookie headers, or "".
std::string CookieValue(const httplib::Request& req, const std::string& name) {
    const size_t headers = req.get_header_value_count("Cookie");
    for (size_t h = 0; h < headers; ++h) {
        const std::string cookies = req.get_header_value("Cookie", h);
        size_t at = 0;
        while (at < cookies.size()) {
            size_t end = cookies.find(';', at);
            if (end == std::string::npos) end = cookies.size();
            std::string pair = cookies.substr(at, end - at);
            const size_t first = pair.find_first_not_of(' ');
            pair = first == std::string::npos ? "" : pair.substr(first);
            if (pair.rfind(name + "=", 0) == 0) return PercentDecode(pair.substr(name.size() + 1));
            at = end + 1;
        }
    }
    return "";
}

// The token a request presents: "?token=" (the link that logs a browser in), the
// Authorization header's bearer token, or the cookie.
std::string RequestToken(const httplib::Request& req) {
    if (req.has_param("token")) return req.get_param_value("token");
    const std::string header = req.get_header_value("Authorization");
    if (header.rfind(kBearerPrefix, 0) == 0) return header.substr(std::strlen(kBearerPrefix));
    return CookieValue(req, kTokenCookie);
}

std::string Peer(const httplib::Request& req) {
    return fmt::format("http:{}:{}", req.remote_addr, req.remote_port);
}

std::string HtmlEscape(const std::string& text) {
    std::string out;
    for (char c : text) {
        switch (c) {
            case '&':
                out += "&amp;";
                break;
            case '<':
                out += "&lt;";
                break;
            case '>':
                out += "&gt;";
                break;
            case '"':
                out += "&quot;";
                break;
            default:
                out += c;
        }
    }
    return out;
}

const char* ContentType(std::string_view name) {
    auto ends_with = [&](std::string_view suffix) {
        return name.size() >= suffix.size() && name.substr(name.size() - suffix.size()) == suffix;
    };
    if (ends_with(".html")) return "text/html; charset=utf-8";
    if (ends_with(".js")) return "text/javascript; charset=utf-8";
    if (ends_with(".css")) return "text/css; charset=utf-8";
    return "application/octet-stream";
}

// Sends an asset of coordinator/dashboard/.
void SendAsset(httplib::Response& res, const std::string& name, int status = 200) {
    const DashboardAsset* asset = FindDashboardAsset(name);
    if (!asset) {
        SendError(res, 500, name + " is not built into this coordinator");
        return;
    }
    res.status = status;
    res.set_header("Cache-Control", "no-cache");
    res.set_content(std::string(asset->bytes), ContentType(name));
}

// The login form, saying why it is shown.
void SendLogin(httplib::Response& res, int status, const std::string& message) {
    const DashboardAsset* asset = FindDashboardAsset("login.html");
    std::string page = asset ? std::string(asset->bytes) : "<p><!--message--></p>";
    const std::string mark = "<!--message-->";
    if (const size_t at = page.find(mark); at != std::string::npos)
        page.replace(at, mark.size(), HtmlEscape(message));
    res.status = status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(page, "text/html; charset=utf-8");
}

bool IsApiPath(const std::string& path) {
    return path.rfind("/api/", 0) == 0 || path == "/metrics";
}

}  // namespace

HttpServerOptions DashboardOptions(const std::string& listen, const ListenSecurity& security,
                                   bool tokens_enabled) {
    std::string host, port;
    if (!SplitHostPort(listen, &host, &port))
        throw std::runtime_error("--http-listen must be HOST:PORT, not '" + listen + "'");
    HttpServerOptions options;
    options.listen = listen;
    options.tls_cert_file = security.tls_cert_file;
    options.tls_key_file = security.tls_key_file;
    if (IsLoopbackAddress(listen)) return options;
    std::string missing;
    if (security.tls_cert_file.empty() || security.tls_key_file.empty())
        missing = "TLS (--tls-cert, --tls-key)";
    if (!tokens_enabled)
        missing += std::string(missing.empty() ? "" : " and ") + "tokens (--tokens)";
    if (missing.empty()) return options;
    throw std::runtime_error(
        "refusing to serve the dashboard on " + listen + " without " + missing +
        ": anyone who reaches the port could cancel jobs and read frames. Serve it on "
        "127.0.0.1 (and reach it through an SSH tunnel), or give the coordinator " +
        missing + " (--insecure does not apply to the dashboard)");
}

struct HttpServer::Impl {
    Impl(Coordinator& c, const Authenticator& a, std::function<std::string()> m)
        : coordinator(c), auth(a), metrics(std::move(m)), previews(c, 8) {}

    // The caller of a request, or nullopt after answering 401 or 403.
    std::optional<Caller> Admit(const httplib::Request& req, httplib::Response& res) const;
    // The pre-routing step: refuses requests without a client token (farms with tokens),
    // logs a browser in from "?token=".
    httplib::Server::HandlerResponse Authenticate(const httplib::Request& req,
                                                  httplib::Response& res) const;
    void Login(const httplib::Request& req, httplib::Response& res) const;
    std::string SessionCookie(const std::string& token) const;
    void AddRoutes(httplib::Server& server);
    // POST routes: the caller (for the log line and its limits) and the handler.
    void Mutating(const httplib::Request& req, httplib::Response& res, const std::string& what,
                  const std::function<json(const Caller&)>& handler);

    Coordinator& coordinator;
    const Authenticator& auth;
    std::function<std::string()> metrics;
    FramePreviews previews;
    bool https = false;
    std::unique_ptr<httplib::Server> server;
    std::thread thread;
    std::atomic<bool> finished{false};
    std::string url;
};

std::optional<Caller> HttpServer::Impl::Admit(const httplib::Request& req,
                                              httplib::Response& res) const {
    Caller caller;
    caller.peer = Peer(req);
    const grpc::Status status = auth.CheckToken(RequestToken(req), Role::kClient, &caller);
    if (status.ok()) return caller;
    const int code = status.error_code() == grpc::StatusCode::PERMISSION_DENIED ? 403 : 401;
    spdlog::warn("dashboard request {} {} refused for {}: {}", req.method, req.path, caller.peer,
                 status.error_message());
    if (IsApiPath(req.path)) {
        if (code == 401) res.set_header("WWW-Authenticate", "Bearer");
        SendError(res, code, status.error_message());
    } else {
        SendLogin(res, code, status.error_message());
    }
    return std::nullopt;
}

httplib::Server::HandlerResponse HttpServer::Impl::Authenticate(const httplib::Request& req,
                                                                httplib::Response& res) const {
    using Result = httplib::Server::HandlerResponse;
    if (!auth.Enabled() || req.path == "/login") return Result::Unhandled;
    if (!Admit(req, res)) return Result::Handled;
    if (req.method == "GET" && req.has_param("token")) {
        // Keep the token out of the address bar and the history: a cookie, then the page.
        res.set_header("Set-Cookie", SessionCookie(req.get_param_value("token")));
        res.set_redirect(req.path, 303);
        return Result::Handled;
    }
    return Result::Unhandled;
}

std::string HttpServer::Impl::SessionCookie(const std::string& token) const {
    return fmt::format("{}={}; Path=/; HttpOnly; SameSite=Strict{}", kTokenCookie,
                       PercentEncode(token), https ? "; Secure" : "");
}

void HttpServer::Impl::Login(const httplib::Request& req, httplib::Response& res) const {
    if (!auth.Enabled()) {
        res.set_redirect("/", 303);
        return;
    }
    if (req.method == "GET") {
        SendLogin(res, 200, "This farm needs a client token (tessera token --role client).");
        return;
    }
    const std::string token = req.has_param("token") ? req.get_param_value("token") : "";
    Caller caller;
    const grpc::Status status = auth.CheckToken(token, Role::kClient, &caller);
    if (!status.ok()) {
        spdlog::warn("dashboard login refused for {}: {}", Peer(req), status.error_message());
        SendLogin(res, status.error_code() == grpc::StatusCode::PERMISSION_DENIED ? 403 : 401,
                  status.error_message());
        return;
    }
    spdlog::info("dashboard login of client '{}' from {}", caller.name, Peer(req));
    res.set_header("Set-Cookie", SessionCookie(token));
    res.set_redirect("/", 303);
}

void HttpServer::Impl::Mutating(const httplib::Request& req, httplib::Response& res,
                                const std::string& what,
                                const std::function<json(const Caller&)>& handler) {
    Guarded(res, [&] {
        Caller caller;
        caller.peer = Peer(req);
        // Admitted before routing; this fills in who it is.
        if (!auth.CheckToken(RequestToken(req), Role::kClient, &caller).ok())
            ThrowError(ErrorCode::kFailedPrecondition, "the token is no longer valid");
        json result = handler(caller);
        LogMutatingCall(caller, "dashboard: " + what);
        SendJson(res, 200, result);
    });
}

void HttpServer::Impl::AddRoutes(httplib::Server& s) {
    using httplib::Request;
    using httplib::Response;
    s.Get("/", [](const Request&, Response& res) { SendAsset(res, "index.html"); });
    s.Get("/(app\\.js|style\\.css)",
          [](const Request& req, Response& res) { SendAsset(res, req.matches[1]); });
    s.Get("/login", [this](const Request& req, Response& res) { Login(req, res); });
    s.Post("/login", [this](const Request& req, Response& res) { Login(req, res); });

    s.Get("/api/jobs", [this](const Request&, Response& res) {
        Guarded(res, [&] {
            json jobs = json::array();
            for (const v1::JobStatus& job : coordinator.ListJobs()) jobs.push_back(JobJson(job));
            SendJson(res, 200, json{{"jobs", std::move(jobs)}, {"now_unix_ms", NowUnixMs()}});
        });
    });
    s.Get("/api/jobs/" + kSegment, [this](const Request& req, Response& res) {
        Guarded(res,
                [&] { SendJson(res, 200, JobJson(coordinator.GetJob(JobIdOf(req.matches[1])))); });
    });
    s.Get("/api/jobs/" + kSegment + "/log", [this](const Request& req, Response& res) {
        Guarded(res, [&] {
            const std::string job = JobIdOf(req.matches[1]);
            std::optional<int64_t> task;
            if (req.has_param("task"))
                task = ParseInteger(req.get_param_value("task"), "task", 0,
                                    std::numeric_limits<int64_t>::max());
            const int limit =
                req.has_param("limit")
                    ? int(ParseInteger(req.get_param_value("limit"), "limit", 1, kMaxLogLimit))
                    : kDefaultLogLimit;
            json entries = json::array();
            for (const v1::JobLogEntry& e : coordinator.JobLog(job, task, limit))
                entries.push_back(LogEntryJson(e));
            SendJson(res, 200, json{{"job_id", job}, {"entries", std::move(entries)}});
        });
    });
    s.Get("/api/jobs/" + kSegment + "/frames/" + kSegment + "/preview\\.png",
          [this](const Request& req, Response& res) {
              Guarded(res, [&] {
                  const std::string job = JobIdOf(req.matches[1]);
                  int frame = 0;
                  try {
                      frame = int(ParseInteger(req.matches[2], "frame", 0, 10000000));
                  } catch (const CoordinatorError&) {
                      ThrowError(ErrorCode::kNotFound,
                                 fmt::format("{} has no frame '{}'", job, req.matches[2].str()));
                  }
                  const FramePreview preview = previews.Get(job, frame);
                  res.set_header("Cache-Control", "no-cache");
                  res.set_header("X-Tessera-Results",
                                 fmt::format("{}/{}", preview.results_done, preview.results_total));
                  res.set_header("X-Tessera-Final", preview.final ? "1" : "0");
                  res.set_content(preview.png, "image/png");
              });
          });
    s.Get("/api/workers", [this](const Request&, Response& res) {
        Guarded(res, [&] {
            json workers = json::array();
            for (const v1::WorkerStatus& w : coordinator.ListWorkers())
                workers.push_back(WorkerJson(w));
            SendJson(res, 200, json{{"workers", std::move(workers)}, {"now_unix_ms", NowUnixMs()}});
        });
    });

    s.Post("/api/jobs/" + kSegment + "/(cancel|retry|priority)",
           [this](const Request& req, Response& res) {
               const std::string action = req.matches[2];
               Mutating(req, res, action + " " + req.matches[1].str(), [&](const Caller& caller) {
                   const std::string job = JobIdOf(req.matches[1]);
                   if (action == "cancel") return JobJson(coordinator.CancelJob(job));
                   if (action == "retry") return JobJson(coordinator.RetryJob(job));
                   const json body = json::parse(req.body.empty() ? "null" : req.body);
                   if (!body.is_object() || !body.contains("priority") ||
                       !body["priority"].is_number_integer())
                       ThrowError(ErrorCode::kInvalidArgument,
                                  "the body must be {\"priority\": P} with a whole number P");
                   const int64_t p = body["priority"].get<int64_t>();
                   if (p < std::numeric_limits<int>::min() || p > std::numeric_limits<int>::max())
                       ThrowError(ErrorCode::kInvalidArgument,
                                  fmt::format("priority {} is out of range", p));
                   return JobJson(coordinator.SetJobPriority(job, int(p), caller.limits));
               });
           });
    s.Post("/api/workers/" + kSegment + "/(enable|disable)",
           [this](const Request& req, Response& res) {
               const std::string worker = req.matches[1], action = req.matches[2];
               Mutating(req, res, action + " worker " + worker, [&](const Caller&) {
                   return WorkerJson(coordinator.SetWorkerEnabled(worker, action == "enable"));
               });
           });

    s.Get("/metrics", [this](const Request&, Response& res) {
        Guarded(res, [&] {
            if (!metrics) ThrowError(ErrorCode::kNotFound, "this coordinator has no metrics");
            res.set_header("Cache-Control", "no-store");
            res.set_content(metrics(), "text/plain; version=0.0.4; charset=utf-8");
        });
    });
}

HttpServer::HttpServer(Coordinator& coordinator, const Authenticator& auth,
                       std::function<std::string()> metrics)
    : impl_(std::make_unique<Impl>(coordinator, auth, std::move(metrics))) {}

HttpServer::~HttpServer() { Stop(); }

int HttpServer::Start(const HttpServerOptions& options) {
    if (impl_->server) throw std::logic_error("the dashboard is started already");
    std::string host, port_text;
    if (!SplitHostPort(options.listen, &host, &port_text))
        throw std::runtime_error("--http-listen must be HOST:PORT, not '" + options.listen + "'");
    const int port = int(ParseInteger(port_text, "the dashboard's port", 0, 65535));
    impl_->https = !options.tls_cert_file.empty();
    if (impl_->https) {
        auto server = std::make_unique<httplib::SSLServer>(options.tls_cert_file.c_str(),
                                                           options.tls_key_file.c_str());
        if (!server->is_valid())
            throw std::runtime_error(fmt::format(
                "the dashboard cannot serve HTTPS: cannot load the certificate {} or key {}",
                options.tls_cert_file, options.tls_key_file));
        impl_->server = std::move(server);
    } else {
        impl_->server = std::make_unique<httplib::Server>();
    }
    httplib::Server& s = *impl_->server;
    // Not SO_REUSEPORT (httplib's default): a second coordinator must not share the port.
    s.set_socket_options([](socket_t sock) {
        const int one = 1;
        ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    });
    s.set_keep_alive_timeout(kKeepAliveSeconds);
    s.set_read_timeout(10);
    s.set_write_timeout(30);
    s.set_payload_max_length(kMaxRequestBytes);
    s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
        return impl_->Authenticate(req, res);
    });
    s.set_error_handler(httplib::Server::HandlerWithResponse(
        [](const httplib::Request& req, httplib::Response& res) {
            // Only what no handler answered (no such route): handlers' errors have bodies.
            if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
            SendError(res, res.status,
                      res.status == 404
                          ? fmt::format("no such page: {} {}", req.method, req.path)
                          : fmt::format("HTTP {} for {} {}", res.status, req.method, req.path));
            return httplib::Server::HandlerResponse::Handled;
        }));
    s.set_exception_handler(
        [](const httplib::Request&, httplib::Response& res, std::exception_ptr error) {
            Guarded(res, [&] { std::rethrow_exception(error); });
        });
    impl_->AddRoutes(s);

    const int bound =
        port == 0 ? s.bind_to_any_port(host) : (s.bind_to_port(host, port) ? port : -1);
    if (bound <= 0) {
        impl_->server.reset();
        throw std::runtime_error(fmt::format(
            "cannot listen on {}: the port is taken, or the host is not an address of this machine",
            options.listen));
    }
    impl_->finished = false;
    impl_->thread = std::thread([this] {
        impl_->server->listen_after_bind();
        impl_->finished = true;
    });
    // stop() does nothing to a server that is not running yet: wait until it runs.
    while (!s.is_running() && !impl_->finished)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const std::string shown_host = host.find(':') != std::string::npos ? "[" + host + "]" : host;
    impl_->url = fmt::format("{}://{}:{}/", impl_->https ? "https" : "http", shown_host, bound);
    return bound;
}

void HttpServer::Stop() {
    if (!impl_->server) return;
    impl_->server->stop();
    if (impl_->thread.joinable()) impl_->thread.join();
    impl_->server.reset();
}

std::string HttpServer::Url() const { return impl_->url; }

}  // namespace tessera
