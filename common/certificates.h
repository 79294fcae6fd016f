#pragma once

// A small certificate authority for a farm (OpenSSL): the CA, and certificates it signs
// for the coordinator (server) and for workers (mutual TLS). Keys are ECDSA P-256;
// everything is PEM text. `tessera cert` writes these to files; tests make their own.

#include <string>
#include <vector>

namespace tessera {

struct KeyAndCertificate {
    std::string key_pem;  // PKCS#8 private key, unencrypted
    std::string certificate_pem;
};

// A self-signed CA certificate valid for `days` days.
KeyAndCertificate MakeCertificateAuthority(const std::string& common_name, int days);

// A certificate signed by `ca` for `common_name`, good for TLS servers and clients, with
// `names` as subject alternative names (each a DNS name or an IPv4/IPv6 address; a
// server's clients check its address against them). Throws std::runtime_error if `ca`
// does not parse or a name is empty.
KeyAndCertificate MakeCertificate(const KeyAndCertificate& ca, const std::string& common_name,
                                  const std::vector<std::string>& names, int days);

// 32 random bytes (OpenSSL's CSPRNG) as 64 hex digits: a new access token.
std::string NewToken();

}  // namespace tessera
