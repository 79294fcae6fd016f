#pragma once

// The command-line options of a process that connects to the coordinator (the worker,
// `tessera submit` and friends): the TLS files and the token file. The token itself is
// never an option: it would show in `ps` to every user of the machine.

#include <CLI/CLI.hpp>

#include "security.h"

namespace tessera {

inline void AddClientSecurityOptions(CLI::App& app, ClientSecurityFlags& flags,
                                     const std::string& group = "Security") {
    app.add_option("--tls-ca", flags.ca_file,
                   "PEM CA that signed the coordinator's certificate: connect over TLS "
                   "($TESSERA_TLS_CA)")
        ->group(group)
        ->check(CLI::ExistingFile);
    app.add_option("--tls-cert", flags.cert_file,
                   "PEM client certificate for mutual TLS ($TESSERA_TLS_CERT)")
        ->group(group)
        ->check(CLI::ExistingFile);
    app.add_option("--tls-key", flags.key_file, "PEM key of --tls-cert ($TESSERA_TLS_KEY)")
        ->group(group)
        ->check(CLI::ExistingFile);
    app.add_option("--tls-server-name", flags.server_name,
                   "Name the coordinator's certificate carries, if not the address's host "
                   "($TESSERA_TLS_SERVER_NAME)")
        ->group(group);
    app.add_option("--token-file", flags.token_file,
                   "File holding this process's access token (else $TESSERA_TOKEN, or the file "
                   "$TESSERA_TOKEN_FILE names)")
        ->group(group)
        ->check(CLI::ExistingFile);
}

}  // namespace tessera
