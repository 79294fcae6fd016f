#pragma once

// Who may call the coordinator, and how it listens.
//
// Callers present a bearer token ("authorization: Bearer <token>"). Each token has a role:
// a client token submits, watches, cancels and downloads; a worker token registers,
// leases, and reports tasks; both may upload blobs; only workers download them (scene
// bundles and stage artifacts). A token of the wrong role is PERMISSION_DENIED; a missing
// or unknown one UNAUTHENTICATED. With mutual TLS, worker calls must also come with a
// client certificate the farm's CA signed.
//
// Tokens live in a file (never on the command line), one per line:
//
//     # role   name    token (or sha256:<hex of the token>)   [limits]
//     client   alice   4f1c...e9   max_spp=4096 max_resolution=4096 max_priority=10
//     worker   render  9a0b...77
//
// Limits (max_spp, max_resolution, max_frames, max_priority) tighten the coordinator's
// own for jobs that token submits. A coordinator without tokens lets every caller do
// everything: allowed only on loopback (see CheckListenSecurity).

#include <grpcpp/grpcpp.h>

#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "token_limits.h"

namespace tessera {

enum class Role { kClient, kWorker };
const char* RoleName(Role role);

// The authenticated caller of one RPC.
struct Caller {
    std::string name;  // the token's name; "anyone" on a farm without tokens
    Role role = Role::kClient;
    TokenLimits limits;
    std::string peer;  // "ipv4:10.0.0.7:53122"
};

class Authenticator {
  public:
    // Open: every caller is accepted in every role.
    Authenticator() = default;
    // Reads a token file (format above). Throws std::runtime_error naming the file and
    // line of anything malformed, a duplicate token, or a token shorter than 16 chars.
    static Authenticator FromFile(const std::string& path);
    // Parses token-file text; `origin` names it in errors.
    static Authenticator FromText(const std::string& text, const std::string& origin);

    bool Enabled() const { return !tokens_.empty(); }
    int Count(Role role) const;
    // With mutual TLS: worker calls must carry a verified client certificate.
    void RequireWorkerCertificates(bool on) { require_worker_certificates_ = on; }

    // OK with `caller` filled in, or UNAUTHENTICATED / PERMISSION_DENIED with a message
    // that names the method's role but never the expected token.
    grpc::Status Check(const grpc::ServerContextBase& context, Role role, Caller* caller) const;
    // The same for calls both roles may make (blob uploads): the token decides the role.
    grpc::Status CheckAnyRole(const grpc::ServerContextBase& context, Caller* caller) const;
    // The same for a bare token from another transport (the dashboard's HTTP requests):
    // `caller`'s name, role and limits are filled in; its peer is left to the caller.
    grpc::Status CheckToken(std::string_view token, Role role, Caller* caller) const;

  private:
    struct Entry {
        std::string name;
        Role role;
        TokenLimits limits;
    };
    // The token's entry, or null if the call has none or an unknown one (`status` says).
    const Entry* Find(const grpc::ServerContextBase& context, grpc::Status* status) const;

    std::map<std::string, Entry> tokens_;  // by SHA-256 of the token
    bool require_worker_certificates_ = false;
};

// Every caller in every role: a farm without tokens (on loopback).
const Authenticator& OpenAccess();

// For unary handlers: checks the caller; on refusal finishes `reactor` with the status
// and returns false.
bool Admit(const Authenticator& auth, grpc::CallbackServerContext* context, Role role,
           grpc::ServerUnaryReactor* reactor, Caller* caller);

// Logs a call that changes the farm's state, with who made it and from where.
void LogMutatingCall(const Caller& caller, const std::string& what);

// Whether `listen` ("host:port", "unix:path") only accepts connections from this machine.
bool IsLoopbackAddress(const std::string& listen);

struct ListenSecurity {
    std::string tls_cert_file;  // PEM server certificate (chain) and its key
    std::string tls_key_file;
    std::string tls_client_ca_file;  // PEM CA for workers' client certificates (mutual TLS)
    std::string tokens_file;
    bool insecure = false;  // allow plaintext or no tokens off loopback
};

// Refuses (std::runtime_error with the reason and the way out) a coordinator that would
// listen off loopback without TLS and tokens, unless `insecure` is set: then it warns.
void CheckListenSecurity(const std::string& listen, const ListenSecurity& security,
                         bool tokens_enabled);

// The server credentials `security` asks for: TLS with the certificate (and client
// certificates requested and verified against the client CA, when given), or plaintext.
std::shared_ptr<grpc::ServerCredentials> MakeServerCredentials(const ListenSecurity& security);

// A server stream refused before it starts, e.g. for a missing token.
template <typename Message>
class RefusedWriter final : public grpc::ServerWriteReactor<Message> {
  public:
    explicit RefusedWriter(const grpc::Status& status) { this->Finish(status); }
    void OnDone() override { delete this; }
};

template <typename Message>
class RefusedReader final : public grpc::ServerReadReactor<Message> {
  public:
    explicit RefusedReader(const grpc::Status& status) { this->Finish(status); }
    void OnDone() override { delete this; }
};

}  // namespace tessera
