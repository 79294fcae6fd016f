#include "auth.h"

#include <arpa/inet.h>
#include <grpcpp/security/auth_context.h>
#include <grpcpp/security/server_credentials.h>
#include <spdlog/spdlog.h>

#include <sstream>
#include <stdexcept>

#include "security.h"
#include "sha256.h"

namespace tessera {
namespace {

constexpr size_t kMinTokenChars = 16;

std::string Lower(std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// The host part of "host:port", "[v6]:port", "unix:path", "dns:///host:port".
std::string HostOf(std::string listen) {
    if (listen.rfind("dns:///", 0) == 0) listen = listen.substr(7);
    if (!listen.empty() && listen[0] == '[') {
        const size_t close = listen.find(']');
        return close == std::string::npos ? listen : listen.substr(1, close - 1);
    }
    const size_t colon = listen.rfind(':');
    if (colon == std::string::npos) return listen;
    // An IPv6 address without brackets has several colons and no port.
    if (listen.find(':') != colon) return listen;
    return listen.substr(0, colon);
}

int ParseLimit(const std::string& value, const std::string& where) {
    try {
        size_t used = 0;
        const long v = std::stol(value, &used);
        if (used == value.size() && v >= 0 && v <= 1000000000) return static_cast<int>(v);
    } catch (const std::exception&) {
    }
    throw std::runtime_error(where + ": '" + value + "' is not a whole number in 0..1e9");
}

}  // namespace

const char* RoleName(Role role) { return role == Role::kClient ? "client" : "worker"; }

Authenticator Authenticator::FromFile(const std::string& path) {
    return FromText(ReadTextFile(path), path);
}

Authenticator Authenticator::FromText(const std::string& text, const std::string& origin) {
    Authenticator auth;
    std::istringstream lines(text);
    std::string line;
    for (int number = 1; std::getline(lines, line); ++number) {
        const std::string where = origin + ":" + std::to_string(number);
        if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
        std::istringstream words(line);
        std::string role_word, name, token;
        if (!(words >> role_word)) continue;  // blank or comment
        if (!(words >> name >> token))
            throw std::runtime_error(where + ": expected 'ROLE NAME TOKEN [limits]'");
        Entry entry;
        entry.name = name;
        entry.limits.token_name = name;
        if (role_word == "client") {
            entry.role = Role::kClient;
        } else if (role_word == "worker") {
            entry.role = Role::kWorker;
        } else {
            throw std::runtime_error(where + ": the role is 'client' or 'worker', not '" +
                                     role_word + "'");
        }
        std::string key;
        if (token.rfind("sha256:", 0) == 0) {
            key = Lower(token.substr(7));
            if (!IsSha256Hex(key))
                throw std::runtime_error(where + ": sha256: needs 64 hex digits");
        } else {
            if (token.size() < kMinTokenChars)
                throw std::runtime_error(where + ": the token is shorter than " +
                                         std::to_string(kMinTokenChars) +
                                         " characters (make one with `tessera token`)");
            key = Sha256Hex(token);
        }
        std::string limit;
        while (words >> limit) {
            const size_t eq = limit.find('=');
            const std::string field = limit.substr(0, eq);
            if (eq == std::string::npos)
                throw std::runtime_error(where + ": expected LIMIT=VALUE, not '" + limit + "'");
            const int value = ParseLimit(limit.substr(eq + 1), where);
            if (field == "max_spp") {
                entry.limits.max_spp = value;
            } else if (field == "max_resolution") {
                entry.limits.max_resolution = value;
            } else if (field == "max_frames") {
                entry.limits.max_frames = value;
            } else if (field == "max_priority") {
                entry.limits.max_priority = value;
            } else {
                throw std::runtime_error(where + ": unknown limit '" + field +
                                         "' (max_spp, max_resolution, max_frames, max_priority)");
            }
        }
        if (entry.role == Role::kWorker &&
            (entry.limits.max_spp.has_value() || entry.limits.max_resolution ||
             entry.limits.max_frames || entry.limits.max_priority))
            throw std::runtime_error(where + ": limits apply to client tokens only");
        if (!auth.tokens_.emplace(key, entry).second)
            throw std::runtime_error(where + ": the same token appears twice");
    }
    return auth;
}

int Authenticator::Count(Role role) const {
    int n = 0;
    for (const auto& [key, entry] : tokens_) n += entry.role == role;
    return n;
}

const Authenticator::Entry* Authenticator::Find(const grpc::ServerContextBase& context,
                                                grpc::Status* status) const {
    const auto& metadata = context.client_metadata();
    auto it = metadata.find(kAuthorizationKey);
    if (it == metadata.end()) {
        *status = grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                               "this coordinator needs a token (--token-file or $TESSERA_TOKEN)");
        return nullptr;
    }
    const std::string_view header(it->second.data(), it->second.size());
    const std::string_view prefix = kBearerPrefix;
    if (header.substr(0, prefix.size()) != prefix) {
        *status = grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                               "the authorization header is not 'Bearer <token>'");
        return nullptr;
    }
    auto entry = tokens_.find(Sha256Hex(header.substr(prefix.size())));
    if (entry == tokens_.end()) {
        *status = grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "unknown token");
        return nullptr;
    }
    return &entry->second;
}

grpc::Status Authenticator::Check(const grpc::ServerContextBase& context, Role role,
                                  Caller* caller) const {
    caller->peer = context.peer();
    caller->role = role;
    if (role == Role::kWorker && require_worker_certificates_) {
        std::shared_ptr<const grpc::AuthContext> auth = context.auth_context();
        if (!auth || !auth->IsPeerAuthenticated())
            return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                                "worker calls need a client certificate signed by the farm's CA");
    }
    if (tokens_.empty()) {
        caller->name = "anyone";
        return grpc::Status::OK;
    }
    grpc::Status status;
    const Entry* entry = Find(context, &status);
    if (!entry) return status;
    caller->name = entry->name;
    caller->limits = entry->limits;
    if (entry->role != role)
        return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                            std::string("a ") + RoleName(entry->role) + " token ('" + entry->name +
                                "') may not make " + RoleName(role) + " calls");
    return grpc::Status::OK;
}

grpc::Status Authenticator::CheckAnyRole(const grpc::ServerContextBase& context,
                                         Caller* caller) const {
    if (tokens_.empty()) return Check(context, Role::kClient, caller);
    grpc::Status status;
    const Entry* entry = Find(context, &status);
    if (!entry) {
        caller->peer = context.peer();
        return status;
    }
    return Check(context, entry->role, caller);
}

grpc::Status Authenticator::CheckToken(std::string_view token, Role role, Caller* caller) const {
    caller->role = role;
    if (tokens_.empty()) {
        caller->name = "anyone";
        return grpc::Status::OK;
    }
    if (token.empty())
        return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "this coordinator needs a token");
    auto entry = tokens_.find(Sha256Hex(token));
    if (entry == tokens_.end())
        return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "unknown token");
    caller->name = entry->second.name;
    caller->limits = entry->second.limits;
    if (entry->second.role != role)
        return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                            std::string("a ") + RoleName(entry->second.role) + " token ('" +
                                entry->second.name + "') may not make " + RoleName(role) +
                                " calls");
    return grpc::Status::OK;
}

const Authenticator& OpenAccess() {
    static const Authenticator open;
    return open;
}

bool Admit(const Authenticator& auth, grpc::CallbackServerContext* context, Role role,
           grpc::ServerUnaryReactor* reactor, Caller* caller) {
    grpc::Status status = auth.Check(*context, role, caller);
    if (status.ok()) return true;
    spdlog::warn("{} call refused for {}: {}", RoleName(role), caller->peer,
                 status.error_message());
    reactor->Finish(status);
    return false;
}

void LogMutatingCall(const Caller& caller, const std::string& what) {
    spdlog::info("{} by {} '{}' from {}", what, RoleName(caller.role), caller.name, caller.peer);
}

bool IsLoopbackAddress(const std::string& listen) {
    if (listen.rfind("unix:", 0) == 0 || listen.rfind("unix-abstract:", 0) == 0) return true;
    const std::string host = Lower(HostOf(listen));
    if (host == "localhost" || host == "::1") return true;
    unsigned char v4[4];
    return inet_pton(AF_INET, host.c_str(), v4) == 1 && v4[0] == 127;
}

void CheckListenSecurity(const std::string& listen, const ListenSecurity& security,
                         bool tokens_enabled) {
    if (security.tls_cert_file.empty() != security.tls_key_file.empty())
        throw std::runtime_error("TLS needs both --tls-cert and --tls-key");
    if (!security.tls_client_ca_file.empty() && security.tls_cert_file.empty())
        throw std::runtime_error("--tls-client-ca is for TLS: give --tls-cert and --tls-key");
    if (IsLoopbackAddress(listen)) return;
    std::string missing;
    if (security.tls_cert_file.empty()) missing = "TLS (--tls-cert, --tls-key)";
    if (!tokens_enabled)
        missing += std::string(missing.empty() ? "" : " and ") + "tokens (--tokens)";
    if (missing.empty()) return;
    if (!security.insecure)
        throw std::runtime_error("refusing to listen on " + listen + " without " + missing +
                                 ": anyone who reaches the port could submit jobs, read frames "
                                 "and pose as a worker. Listen on 127.0.0.1, add " +
                                 missing +
                                 " (see `tessera cert` and `tessera token`), or pass "
                                 "--insecure on a network you trust");
    spdlog::warn(
        "--insecure: listening on {} without {}; anyone who reaches the port controls "
        "the farm",
        listen, missing);
}

std::shared_ptr<grpc::ServerCredentials> MakeServerCredentials(const ListenSecurity& security) {
    if (security.tls_cert_file.empty()) return grpc::InsecureServerCredentials();
    grpc::SslServerCredentialsOptions ssl(security.tls_client_ca_file.empty()
                                              ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                              : GRPC_SSL_REQUEST_CLIENT_CERTIFICATE_AND_VERIFY);
    grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
    pair.private_key = ReadTextFile(security.tls_key_file);
    pair.cert_chain = ReadTextFile(security.tls_cert_file);
    ssl.pem_key_cert_pairs.push_back(pair);
    if (!security.tls_client_ca_file.empty())
        ssl.pem_root_certs = ReadTextFile(security.tls_client_ca_file);
    return grpc::SslServerCredentials(ssl);
}

}  // namespace tessera
