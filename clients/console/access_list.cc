#include "clients/console/access_list.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/rand.h>
#include <openssl/sha.h>

#include <algorithm>
#include <fstream>
#include <utility>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace bitewise::console {
namespace {

constexpr char kScheme[] = "pbkdf2-sha256";
constexpr int kHashBytes = 32;

absl::StatusOr<std::string> Pbkdf2(const std::string& password,
                                   const std::string& salt, int iterations) {
  std::string out(kHashBytes, '\0');
  if (PKCS5_PBKDF2_HMAC(password.data(), static_cast<int>(password.size()),
                        reinterpret_cast<const unsigned char*>(salt.data()),
                        static_cast<int>(salt.size()), iterations, EVP_sha256(),
                        kHashBytes,
                        reinterpret_cast<unsigned char*>(out.data())) != 1) {
    return absl::InternalError("PBKDF2 failed");
  }
  return out;
}

std::string Sha256(const std::string& bytes) {
  std::string out(SHA256_DIGEST_LENGTH, '\0');
  SHA256(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(),
         reinterpret_cast<unsigned char*>(out.data()));
  return out;
}

bool IsHex(absl::string_view text) {
  if (text.empty() || text.size() % 2 != 0) return false;
  for (char c : text) {
    if (!absl::ascii_isxdigit(static_cast<unsigned char>(c))) return false;
  }
  return true;
}

}  // namespace

const char* RoleName(Role role) {
  switch (role) {
    case Role::kLocal:
      return "local";
    case Role::kCaregiver:
      return "caregiver";
    case Role::kResearcher:
      return "researcher";
  }
  return "unknown";
}

absl::StatusOr<std::string> HashPassword(const std::string& password,
                                         int iterations) {
  std::string salt(16, '\0');
  if (RAND_bytes(reinterpret_cast<unsigned char*>(salt.data()),
                 static_cast<int>(salt.size())) != 1) {
    return absl::InternalError("the system's random source failed");
  }
  absl::StatusOr<std::string> hash = Pbkdf2(password, salt, iterations);
  if (!hash.ok()) return hash.status();
  return absl::StrCat(kScheme, "$", iterations, "$",
                      absl::BytesToHexString(salt), "$",
                      absl::BytesToHexString(*hash));
}

AccessList::AccessList(const AccessList& other)
    : entries_(other.entries_), decoy_(other.decoy_) {}

absl::StatusOr<AccessList> AccessList::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot read the access file ", path));
  }
  AccessList list;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    absl::string_view text = line;
    const size_t hash = text.find('#');
    if (hash != absl::string_view::npos) text = text.substr(0, hash);
    text = absl::StripAsciiWhitespace(text);
    if (text.empty()) continue;
    const auto where = [&] { return absl::StrCat(path, ":", number, ": "); };
    std::vector<absl::string_view> fields =
        absl::StrSplit(text, absl::ByAnyChar(" \t"), absl::SkipEmpty());
    if (fields.size() != 3) {
      return absl::InvalidArgumentError(absl::StrCat(
          where(), "expected NAME ROLE HASH, got ", fields.size(), " fields"));
    }
    Entry entry;
    if (fields[1] == "caregiver") {
      entry.role = Role::kCaregiver;
    } else if (fields[1] == "researcher") {
      entry.role = Role::kResearcher;
    } else {
      return absl::InvalidArgumentError(
          absl::StrCat(where(), "unknown role \"", fields[1],
                       "\" (caregiver or researcher)"));
    }
    std::vector<absl::string_view> parts = absl::StrSplit(fields[2], '$');
    if (parts.size() != 4 || parts[0] != kScheme ||
        !absl::SimpleAtoi(parts[1], &entry.iterations) ||
        entry.iterations < 1000 || !IsHex(parts[2]) || !IsHex(parts[3]) ||
        parts[3].size() != 2 * kHashBytes) {
      return absl::InvalidArgumentError(
          absl::StrCat(where(), "the hash must be ", kScheme,
                       "$ITERATIONS(>=1000)$SALT_HEX$HASH_HEX(64 digits), as "
                       "bitewise-console --hash_password prints"));
    }
    entry.salt = absl::HexStringToBytes(parts[2]);
    entry.hash = absl::HexStringToBytes(parts[3]);
    if (!list.entries_.emplace(std::string(fields[0]), entry).second) {
      return absl::InvalidArgumentError(
          absl::StrCat(where(), "\"", fields[0], "\" is listed twice"));
    }
  }
  if (list.entries_.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("the access file ", path, " lists no credentials"));
  }
  for (const auto& [name, entry] : list.entries_) {
    list.decoy_.iterations = std::max(list.decoy_.iterations, entry.iterations);
  }
  return list;
}

absl::StatusOr<Role> AccessList::Check(const std::string& name,
                                       const std::string& password) const {
  const absl::Status wrong =
      absl::UnauthenticatedError("wrong name or password");
  auto it = entries_.find(name);
  const bool listed = it != entries_.end();
  const Entry& entry = listed ? it->second : decoy_;
  const std::string key =
      Sha256(absl::StrCat(name, std::string(1, '\0'), password));
  {
    absl::MutexLock lock(&mu_);
    if (verified_.count(key) > 0) return entry.role;
    if (checks_running_ > 0) {
      if (checks_waiting_ >= kMaxWaitingChecks) {
        return absl::ResourceExhaustedError(
            absl::StrCat("too many password checks at once (one running, ",
                         checks_waiting_, " waiting): try again in a moment"));
      }
      ++checks_waiting_;
      mu_.Await(absl::Condition(this, &AccessList::NoCheckRunning));
      --checks_waiting_;
      // The check that ran may have been this password's.
      if (verified_.count(key) > 0) return entry.role;
    }
    ++checks_running_;
  }
  absl::StatusOr<std::string> hash =
      Pbkdf2(password, entry.salt, entry.iterations);
  absl::MutexLock lock(&mu_);
  --checks_running_;
  ++derivations_;
  if (!hash.ok()) return hash.status();
  if (!listed ||
      CRYPTO_memcmp(hash->data(), entry.hash.data(), kHashBytes) != 0) {
    return wrong;
  }
  verified_.insert(key);
  return entry.role;
}

}  // namespace bitewise::console
