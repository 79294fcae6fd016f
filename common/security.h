#pragma once

// How the farm's processes reach the coordinator: over TLS (the coordinator's
// certificate checked against a CA, and optionally a client certificate for mutual TLS)
// or plaintext on loopback, with a bearer token sent on every call as
// "authorization: Bearer <token>". Tokens come from a file or the environment, never
// from the command line, where any user of the machine could read them.

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace tessera {

// The metadata key and scheme a token travels under.
inline constexpr const char* kAuthorizationKey = "authorization";
inline constexpr const char* kBearerPrefix = "Bearer ";

struct ClientSecurity {
    std::string ca_file;    // PEM: the CA that signed the coordinator's certificate.
                            // Empty: plaintext (loopback farms).
    std::string cert_file;  // PEM client certificate and key, for mutual TLS (optional)
    std::string key_file;
    std::string server_name;  // the name the coordinator's certificate must carry, when
                              // it is not the host part of the address
    std::string token;        // sent on every call; empty: none

    bool Tls() const { return !ca_file.empty(); }
};

// The security settings as a user gives them: files, and the environment as a fallback.
struct ClientSecurityFlags {
    std::string ca_file, cert_file, key_file, server_name;
    std::string token_file;

    // Files named by flags, else $TESSERA_TLS_CA, $TESSERA_TLS_CERT, $TESSERA_TLS_KEY,
    // $TESSERA_TLS_SERVER_NAME; the token from token_file, else $TESSERA_TOKEN (the
    // token itself), else the file $TESSERA_TOKEN_FILE names. Throws
    // std::runtime_error naming the file or variable that is wrong.
    ClientSecurity Resolve() const;
};

// A secret kept in a file: its content without surrounding whitespace. Throws
// std::runtime_error if the file cannot be read or holds nothing; warns if every user of
// the machine may read it.
std::string ReadSecretFile(const std::string& path);
// The whole file; throws std::runtime_error naming it.
std::string ReadTextFile(const std::string& path);

// A channel to `address` with `security`: TLS credentials when a CA is given, the token
// added to every call's metadata. Throws std::runtime_error if a file cannot be read.
std::shared_ptr<grpc::Channel> MakeChannel(const std::string& address,
                                           const ClientSecurity& security,
                                           grpc::ChannelArguments args);

}  // namespace tessera
