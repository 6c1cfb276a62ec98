// The console's access file (clients/console/access_list.h): PBKDF2-SHA256
// checked against published test vectors, fresh salts, roles, and every
// malformed line refused naming the file and the line.
#include "clients/console/access_list.h"

#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/common/status_matchers.h"

namespace bitewise::console {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::AllOf;
using ::testing::HasSubstr;

// PBKDF2-HMAC-SHA256 of "password" with the salt "salt" ("73616c74"), 4096
// iterations, 32 bytes; and of "Password" with "NaCl" ("4e61436c"), 80000
// iterations (RFC 7914, section 11: the first 32 of its 64 bytes).
constexpr char kPasswordSalt4096[] =
    "pbkdf2-sha256$4096$73616c74$"
    "c5e478d59288c841aa530db6845c4c8d962893a001ce4e11a4963873aa98134a";
constexpr char kPasswordNaCl80000[] =
    "pbkdf2-sha256$80000$4e61436c$"
    "4ddcd8f60b98be21830cee5ef22701f9641a4418d04c0414aeff08876b34ab56";

class AccessFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string base = ::testing::TempDir();
    if (base.empty() || base.back() != '/') base += '/';
    std::string pattern = base + "access_list_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << pattern;
    dir_ = pattern;
    path_ = dir_ + "/access";
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  void Write(const std::string& text) {
    std::ofstream out(path_, std::ios::trunc);
    out << text;
  }

  std::string dir_;
  std::string path_;
};

TEST_F(AccessFileTest, PasswordsAreCheckedAgainstPublishedPbkdf2Vectors) {
  Write(absl::StrCat("# the console's people\n\n", "carol caregiver ",
                     kPasswordSalt4096, "  # the table\n", "rex\tresearcher\t",
                     kPasswordNaCl80000, "\n"));
  absl::StatusOr<AccessList> access = AccessList::Load(path_);
  ASSERT_THAT(access, IsOk());
  EXPECT_EQ(access->size(), 2);
  EXPECT_THAT(access->Check("carol", "password"), IsOk());
  EXPECT_EQ(*access->Check("carol", "password"), Role::kCaregiver);
  EXPECT_EQ(*access->Check("rex", "Password"), Role::kResearcher);
  // Verified once and remembered, a password still opens only its own name.
  EXPECT_EQ(*access->Check("carol", "password"), Role::kCaregiver);
  for (const auto& [name, password] :
       std::vector<std::pair<std::string, std::string>>{
           {"carol", "Password"},
           {"carol", "password "},
           {"carol", ""},
           {"rex", "password"},
           {"nobody", "password"},
           {"", ""},
       }) {
    // The same words whichever is wrong, so a guess learns nothing.
    EXPECT_THAT(
        access->Check(name, password),
        StatusIs(absl::StatusCode::kUnauthenticated, "wrong name or password"))
        << name << " / " << password;
  }
  // A copy checks the same.
  const AccessList copy(*access);
  EXPECT_EQ(*copy.Check("rex", "Password"), Role::kResearcher);
  EXPECT_FALSE(copy.Check("rex", "password").ok());
}

// A name that is not listed costs the same derivation as a listed one (at
// the file's highest iteration count), so the time of a wrong answer does
// not tell which names exist; it never opens anything.
TEST_F(AccessFileTest, AnUnlistedNameCostsAsMuchAsAListedOne) {
  Write(absl::StrCat("carol caregiver ", kPasswordSalt4096, "\n"));
  absl::StatusOr<AccessList> access = AccessList::Load(path_);
  ASSERT_THAT(access, IsOk());
  EXPECT_EQ(access->derivations(), 0);
  EXPECT_FALSE(access->Check("carol", "wrong").ok());
  EXPECT_EQ(access->derivations(), 1);
  EXPECT_THAT(
      access->Check("nobody", "password"),
      StatusIs(absl::StatusCode::kUnauthenticated, "wrong name or password"));
  EXPECT_EQ(access->derivations(), 2);
  EXPECT_FALSE(access->Check("nobody", "password").ok());  // never cached
  EXPECT_EQ(access->derivations(), 3);
}

TEST_F(AccessFileTest, HashedPasswordsHaveAFreshSaltAndVerify) {
  absl::StatusOr<std::string> first = HashPassword("table-pass", 1000);
  absl::StatusOr<std::string> second = HashPassword("table-pass", 1000);
  ASSERT_THAT(first, IsOk());
  ASSERT_THAT(second, IsOk());
  EXPECT_NE(*first, *second);
  const std::vector<std::string> parts = absl::StrSplit(*first, '$');
  ASSERT_EQ(parts.size(), 4u);
  EXPECT_EQ(parts[0], "pbkdf2-sha256");
  EXPECT_EQ(parts[1], "1000");
  EXPECT_EQ(parts[2].size(), 32u);  // 16 bytes
  EXPECT_EQ(parts[3].size(), 64u);  // 32 bytes
  EXPECT_EQ(parts[2].find_first_not_of("0123456789abcdef"), std::string::npos);
  EXPECT_EQ(parts[3].find_first_not_of("0123456789abcdef"), std::string::npos);

  Write(absl::StrCat("a caregiver ", *first, "\nb researcher ", *second, "\n"));
  absl::StatusOr<AccessList> access = AccessList::Load(path_);
  ASSERT_THAT(access, IsOk());
  EXPECT_EQ(*access->Check("a", "table-pass"), Role::kCaregiver);
  EXPECT_EQ(*access->Check("b", "table-pass"), Role::kResearcher);
  EXPECT_FALSE(access->Check("a", "table-pasS").ok());
  EXPECT_EQ(access->Check("a", "x").status().code(),
            absl::StatusCode::kUnauthenticated);
}

TEST_F(AccessFileTest, EachMalformedLineIsRefusedNamingTheFileAndLine) {
  const std::string good = kPasswordSalt4096;
  const std::string weak =
      "pbkdf2-sha256$999$73616c74$"
      "c5e478d59288c841aa530db6845c4c8d962893a001ce4e11a4963873aa98134a";
  struct Case {
    std::string line;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"carol caregiver", "expected NAME ROLE HASH, got 2 fields"},
      {"carol caregiver " + good + " extra",
       "expected NAME ROLE HASH, got 4 fields"},
      {"carol chef " + good, "unknown role \"chef\" (caregiver or researcher)"},
      {"carol local " + good, "unknown role \"local\""},
      {"carol caregiver " + weak, "ITERATIONS(>=1000)"},
      {"carol caregiver pbkdf2-sha1" + good.substr(13), "the hash must be"},
      {"carol caregiver pbkdf2-sha256$4096$7361zz74$" + good.substr(28),
       "the hash must be"},
      {"carol caregiver pbkdf2-sha256$4096$73616c7$" + good.substr(28),
       "the hash must be"},
      {"carol caregiver " + good.substr(0, good.size() - 2),
       "HASH_HEX(64 digits)"},
      {"carol caregiver " + good + "$", "the hash must be"},
      {"carol caregiver pbkdf2-sha256$many$73616c74$" + good.substr(28),
       "the hash must be"},
  };
  for (const Case& c : cases) {
    // A comment and a blank line first: the line numbers count them.
    Write("# people\n\n" + c.line + "\n");
    EXPECT_THAT(
        AccessList::Load(path_),
        StatusIs(absl::StatusCode::kInvalidArgument,
                 AllOf(HasSubstr(path_ + ":3: "), HasSubstr(c.message))))
        << c.line;
  }
  Write(absl::StrCat("carol caregiver ", good, "\nrex researcher ",
                     kPasswordNaCl80000, "\ncarol researcher ", good, "\n"));
  EXPECT_THAT(AccessList::Load(path_),
              StatusIs(absl::StatusCode::kInvalidArgument,
                       AllOf(HasSubstr(path_ + ":3: "),
                             HasSubstr("\"carol\" is listed twice"))));
}

TEST_F(AccessFileTest, AFileWithoutCredentialsOrUnreadableIsRefused) {
  for (const std::string& text :
       {std::string(), std::string("# nobody yet\n\n   \t\n")}) {
    Write(text);
    EXPECT_THAT(
        AccessList::Load(path_),
        StatusIs(absl::StatusCode::kInvalidArgument,
                 AllOf(HasSubstr(path_), HasSubstr("lists no credentials"))));
  }
  EXPECT_THAT(
      AccessList::Load(path_ + ".absent"),
      StatusIs(absl::StatusCode::kFailedPrecondition,
               HasSubstr("cannot read the access file " + path_ + ".absent")));
  EXPECT_THAT(AccessList::Load(dir_ + "/no/such/dir/access"),
              StatusIs(absl::StatusCode::kFailedPrecondition,
                       HasSubstr("cannot read")));
}

TEST(RoleTest, RolesHaveTheirNames) {
  EXPECT_STREQ(RoleName(Role::kLocal), "local");
  EXPECT_STREQ(RoleName(Role::kCaregiver), "caregiver");
  EXPECT_STREQ(RoleName(Role::kResearcher), "researcher");
  EXPECT_STREQ(RoleName(static_cast<Role>(9)), "unknown");
}

}  // namespace
}  // namespace bitewise::console
