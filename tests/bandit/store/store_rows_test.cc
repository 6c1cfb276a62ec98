// The encodings and row checks both stores share (store_rows.h): vectors and
// priors as little-endian float64 bytes, page tokens and pages, the
// checks' report, action names, and rows read back through a real SQLite
// statement.
#include "services/bandit/store/store_rows.h"

#include <sqlite3.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/bandit/store/event_checksum.h"
#include "services/bandit/store/sqlite_helpers.h"
#include "tests/common/status_matchers.h"

namespace bitewise::bandit::store_rows {
namespace {

using ::bitewise::testing::IsOk;
using ::bitewise::testing::StatusIs;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

uint64_t BitsOf(double value) {
  uint64_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  return bits;
}

double FromBits(uint64_t bits) {
  double value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

// The bytes of `values` as the documented format has them, computed here
// with shifts rather than the encoder's loop: least significant byte first.
std::string LittleEndian(const std::vector<double>& values) {
  std::string out;
  for (double value : values) {
    const uint64_t bits = BitsOf(value);
    for (int shift = 0; shift < 64; shift += 8) {
      out.push_back(static_cast<char>(static_cast<uint8_t>(bits >> shift)));
    }
  }
  return out;
}

TEST(StoreRowsTest, DoublesAreEncodedLittleEndianBitForBit) {
  EXPECT_EQ(EncodeDoubles({1.0}),
            std::string("\x00\x00\x00\x00\x00\x00\xf0\x3f", 8));
  EXPECT_EQ(EncodeDoubles({-0.0}),
            std::string("\x00\x00\x00\x00\x00\x00\x00\x80", 8));
  const std::vector<double> values = {
      0.1 + 0.2,
      -0.0,
      std::numeric_limits<double>::denorm_min(),
      std::numeric_limits<double>::infinity(),
      -std::numeric_limits<double>::max(),
      FromBits(0x7ff8000000000123),  // a NaN with a payload
  };
  const std::string bytes = EncodeDoubles(values);
  EXPECT_EQ(bytes, LittleEndian(values));
  absl::StatusOr<std::vector<double>> decoded = DecodeDoubles(bytes, "v");
  ASSERT_THAT(decoded, IsOk());
  ASSERT_EQ(decoded->size(), values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(BitsOf((*decoded)[i]), BitsOf(values[i])) << i;
  }
  EXPECT_EQ(EncodeDoubles({}), "");
  EXPECT_THAT(DecodeDoubles("", "v"), IsOk());
  EXPECT_TRUE(DecodeDoubles("", "v")->empty());
}

TEST(StoreRowsTest, BytesThatAreNotWholeDoublesAreDataLossNamingThem) {
  const std::string bytes = EncodeDoubles({1.0, 2.0}).substr(0, 13);
  EXPECT_THAT(DecodeDoubles(bytes, "event 7 context"),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("event 7 context"),
                             HasSubstr("13 bytes, not a multiple of 8"))));
}

PopulationPrior TwoActionPrior() {
  PopulationPrior prior;
  prior.pool_version = 12;
  prior.rounds = 2.5;
  prior.context_msn = 1.0 / 3;
  prior.posthoc_msn = 0.75;
  prior.theta0 = {{1.0, -2.0, 0.1}, {4.0, 5.0, -0.0}};
  prior.phi0 = {{7.0}, {-8.5}};
  return prior;
}

TEST(StoreRowsTest, APriorIsOneArrayOfHeaderThetaAndPhi) {
  const PopulationPrior prior = TwoActionPrior();
  // pool_version, rounds, context_msn, posthoc_msn, K, d, q, theta0, phi0.
  const std::string expected =
      LittleEndian({12, 2.5, 1.0 / 3, 0.75, 2, 3, 1, 1.0, -2.0, 0.1, 4.0, 5.0,
                    -0.0, 7.0, -8.5});
  EXPECT_EQ(EncodePrior(prior), expected);

  absl::StatusOr<PopulationPrior> decoded = DecodePrior(expected, "p");
  ASSERT_THAT(decoded, IsOk());
  EXPECT_EQ(decoded->pool_version, 12);
  EXPECT_EQ(BitsOf(decoded->rounds), BitsOf(2.5));
  EXPECT_EQ(BitsOf(decoded->context_msn), BitsOf(1.0 / 3));
  EXPECT_EQ(BitsOf(decoded->posthoc_msn), BitsOf(0.75));
  EXPECT_EQ(decoded->theta0, prior.theta0);
  EXPECT_EQ(BitsOf(decoded->theta0[1][2]), BitsOf(-0.0));
  EXPECT_EQ(decoded->phi0, prior.phi0);
}

TEST(StoreRowsTest, AContextOnlyPriorHasNoPhi) {
  PopulationPrior prior = TwoActionPrior();
  prior.phi0.clear();
  const std::string bytes = EncodePrior(prior);
  EXPECT_EQ(bytes, LittleEndian({12, 2.5, 1.0 / 3, 0.75, 2, 3, 0, 1.0, -2.0,
                                 0.1, 4.0, 5.0, -0.0}));
  absl::StatusOr<PopulationPrior> decoded = DecodePrior(bytes, "p");
  ASSERT_THAT(decoded, IsOk());
  EXPECT_EQ(decoded->theta0, prior.theta0);
  EXPECT_TRUE(decoded->phi0.empty());
}

TEST(StoreRowsTest, MalformedPriorsAreDataLossNamingWhatHeldThem) {
  const std::vector<std::vector<double>> malformed = {
      {},                                    // no header
      {1, 1, 1, 1, 1, 1},                    // short header
      {1, 1, 1, 1, -1, 1, 0},                // negative K
      {1, 1, 1, 1, 1.5, 1, 0, 0, 0},         // fractional K
      {1, 1, 1, 1, 1, 70000, 0},             // d past 2^16
      {1, 1, 1, 1, 1, NAN, 0},               // NaN d
      {1, 1, 1, 1, 2, 1, 0, 5},              // one theta value missing
      {1, 1, 1, 1, 1, 1, 1, 5, 6, 7},        // one value too many
      {1, 1, 1, 1, 1, INFINITY, 0, 5, 6.0},  // infinite d
  };
  for (const std::vector<double>& values : malformed) {
    EXPECT_THAT(DecodePrior(LittleEndian(values), "user \"ann\" prior"),
                StatusIs(absl::StatusCode::kDataLoss,
                         AllOf(HasSubstr("user \"ann\" prior"),
                               HasSubstr("malformed"))))
        << ::testing::PrintToString(values);
  }
  EXPECT_THAT(DecodePrior(std::string(9, '\0'), "pool 3"),
              StatusIs(absl::StatusCode::kDataLoss, HasSubstr("pool 3")));
}

TEST(StoreRowsTest, PageTokensCarryPrintableKeysOnlyForTheirOwnListing) {
  // Keys are user ids and decimal ids; these characters would need escaping
  // in a URL if the token were not base64.
  const std::string key("a/b+c?=&%user~");
  const std::string token = MakePageToken('u', key);
  // Printable in a URL: web-safe base64 of "u:" and the key.
  std::string raw;
  ASSERT_TRUE(absl::WebSafeBase64Unescape(token, &raw));
  EXPECT_EQ(raw, "u:" + key);
  EXPECT_EQ(token.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmn"
                                    "opqrstuvwxyz0123456789-_"),
            std::string::npos)
      << token;
  absl::StatusOr<std::string> parsed = ParsePageToken(token, 'u');
  ASSERT_THAT(parsed, IsOk());
  EXPECT_EQ(*parsed, key);
  EXPECT_THAT(ParsePageToken(MakePageToken('u', ""), 'u'), IsOk());

  // Another listing's token, garbage, and a token without its separator.
  for (const std::string& bad :
       {MakePageToken('e', key), std::string("!!!"), std::string(""),
        absl::WebSafeBase64Escape("u"), absl::WebSafeBase64Escape("u;x"),
        // Bytes no key has: PostgreSQL would refuse them naming itself.
        absl::WebSafeBase64Escape(std::string("u:\xff")),
        absl::WebSafeBase64Escape(std::string("u:a\0b", 5))}) {
    EXPECT_THAT(ParsePageToken(bad, 'u'),
                StatusIs(absl::StatusCode::kInvalidArgument,
                         HasSubstr("invalid page_token")))
        << bad;
  }
}

TEST(StoreRowsTest, IdPageTokensTakeOnlyPositiveIds) {
  absl::StatusOr<int64_t> id = ParseIdPageToken(MakePageToken('e', "42"), 'e');
  ASSERT_THAT(id, IsOk());
  EXPECT_EQ(*id, 42);
  EXPECT_EQ(*ParseIdPageToken(MakePageToken('a', "9223372036854775807"), 'a'),
            std::numeric_limits<int64_t>::max());
  for (const char* key : {"0", "-1", "", "4x", "9223372036854775808"}) {
    EXPECT_THAT(ParseIdPageToken(MakePageToken('e', key), 'e'),
                StatusIs(absl::StatusCode::kInvalidArgument,
                         HasSubstr("invalid page_token")))
        << key;
  }
  EXPECT_THAT(ParseIdPageToken(MakePageToken('a', "42"), 'e'),
              StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("page")));
}

TEST(StoreRowsTest, PageSizesAreClampedToOneThousandAndDefaultToOneHundred) {
  EXPECT_EQ(ClampPageSize(0), 100);
  EXPECT_EQ(ClampPageSize(-7), 100);
  EXPECT_EQ(ClampPageSize(1), 1);
  EXPECT_EQ(ClampPageSize(999), 999);
  EXPECT_EQ(ClampPageSize(1000), 1000);
  EXPECT_EQ(ClampPageSize(1001), 1000);
  EXPECT_EQ(ClampPageSize(std::numeric_limits<int>::max()), 1000);
}

// Feeds `items` through a PageBuilder as the stores do (Room before each
// row, Add after) with `bytes` per item.
PageResult<int> BuildPage(const Page& page, const std::vector<int>& items,
                          int64_t bytes) {
  PageBuilder<int> builder(page, 'e',
                           [](const int& item) { return absl::StrCat(item); });
  for (int item : items) {
    if (!builder.Room()) break;
    if (!builder.Add(item, bytes)) break;
  }
  return builder.Take();
}

TEST(StoreRowsTest, APageEndsAtItsSizeWithATokenAfterTheLastItemKept) {
  Page page;
  page.page_size = 2;
  // The stores read page_size + 1 rows: the extra one only says "more".
  const PageResult<int> full = BuildPage(page, {11, 12, 13}, 10);
  EXPECT_THAT(full.items, ElementsAre(11, 12));
  EXPECT_EQ(*ParseIdPageToken(full.next_page_token, 'e'), 12);
  // No extra row: the listing is done.
  const PageResult<int> last = BuildPage(page, {13}, 10);
  EXPECT_THAT(last.items, ElementsAre(13));
  EXPECT_EQ(last.next_page_token, "");
  // A size of 0 is the default of 100.
  page.page_size = 0;
  std::vector<int> many(150);
  for (int i = 0; i < 150; ++i) many[i] = i + 1;
  const PageResult<int> defaulted = BuildPage(page, many, 10);
  EXPECT_EQ(defaulted.items.size(), 100u);
  EXPECT_EQ(*ParseIdPageToken(defaulted.next_page_token, 'e'), 100);
}

TEST(StoreRowsTest, APageEndsBeforeItsByteBudgetButNeverBeforeItsFirstItem) {
  Page page;
  page.page_size = 10;
  page.max_bytes = 25;
  const PageResult<int> budgeted = BuildPage(page, {1, 2, 3, 4}, 10);
  EXPECT_THAT(budgeted.items, ElementsAre(1, 2));
  EXPECT_EQ(*ParseIdPageToken(budgeted.next_page_token, 'e'), 2);
  // Exactly the budget still fits.
  page.max_bytes = 30;
  EXPECT_THAT(BuildPage(page, {1, 2, 3, 4}, 10).items, ElementsAre(1, 2, 3));
  // One item over the budget alone is still a page of one.
  page.max_bytes = 5;
  const PageResult<int> one = BuildPage(page, {1, 2}, 100);
  EXPECT_THAT(one.items, ElementsAre(1));
  EXPECT_EQ(*ParseIdPageToken(one.next_page_token, 'e'), 1);
}

TEST(StoreRowsTest, ApproximateSizesGrowWithWhatIsEncoded) {
  UserRecord user;
  user.user_id = "ann";
  user.config.action_names = {"a", "bb"};
  const int64_t bare = ApproxBytes(user);
  user.user_id = "anna";
  EXPECT_EQ(ApproxBytes(user), bare + 1);
  user.config.action_names.push_back("ccc");
  EXPECT_EQ(ApproxBytes(user), bare + 1 + 3 + 4);
  user.config.prior.theta0 = {{1, 2}, {3, 4}, {5, 6}};
  user.config.prior.phi0 = {{1}, {2}, {3}};
  EXPECT_EQ(ApproxBytes(user), bare + 1 + 3 + 4 + 8 * 9);

  EventRecord event;
  event.user_id = "ann";
  const int64_t empty = ApproxBytes(event);
  event.meal_id = "lunch";
  event.item_label = "pea";
  event.context = {1, 2, 3};
  event.posthoc = {4};
  EXPECT_EQ(ApproxBytes(event), empty + 5 + 3 + 8 * 4);
}

TEST(StoreRowsTest, StoredIntegersOutsideAnIntAreDataLossNamingThem) {
  EXPECT_EQ(*ToInt(std::numeric_limits<int>::max(), "x"),
            std::numeric_limits<int>::max());
  EXPECT_EQ(*ToInt(std::numeric_limits<int>::min(), "x"),
            std::numeric_limits<int>::min());
  const int64_t big = int64_t{std::numeric_limits<int>::max()} + 1;
  EXPECT_THAT(ToInt(big, "event 9 action"),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("event 9 action"),
                             HasSubstr("2147483648 is out of range"))));
  EXPECT_THAT(ToInt(int64_t{std::numeric_limits<int>::min()} - 1, "y"),
              StatusIs(absl::StatusCode::kDataLoss, HasSubstr("y")));
}

TEST(StoreRowsTest, NanOutcomesAreInvalidArgumentNamingTheField) {
  EXPECT_THAT(CheckOutcome(0.0, 1.0), IsOk());
  EXPECT_THAT(CheckOutcome(INFINITY, -INFINITY), IsOk());
  EXPECT_THAT(CheckOutcome(NAN, 1.0),
              StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("loss")));
  EXPECT_THAT(
      CheckOutcome(1.0, NAN),
      StatusIs(absl::StatusCode::kInvalidArgument, HasSubstr("weight")));
}

TEST(StoreRowsTest, UnknownLearnerOrStrategyCodesAreDataLoss) {
  for (int learner = 1; learner <= 3; ++learner) {
    for (int strategy = 1; strategy <= 5; ++strategy) {
      EXPECT_THAT(CheckUserCodes(learner, strategy, "u"), IsOk())
          << learner << " " << strategy;
    }
  }
  EXPECT_THAT(CheckUserCodes(0, 1, "user \"ann\""),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("user \"ann\""),
                             HasSubstr("unknown learner 0"))));
  EXPECT_THAT(
      CheckUserCodes(4, 1, "u"),
      StatusIs(absl::StatusCode::kDataLoss, HasSubstr("unknown learner 4")));
  EXPECT_THAT(
      CheckUserCodes(1, 0, "u"),
      StatusIs(absl::StatusCode::kDataLoss, HasSubstr("unknown strategy 0")));
  EXPECT_THAT(
      CheckUserCodes(1, 6, "u"),
      StatusIs(absl::StatusCode::kDataLoss, HasSubstr("unknown strategy 6")));
}

TEST(StoreRowsTest, ActionNamesMustBeNumberedFromZeroWithoutGaps) {
  ActionNamesReader reader("user \"ann\"", "user_actions");
  ASSERT_THAT(reader.Add(0, "fork"), IsOk());
  ASSERT_THAT(reader.Add(1, "tilt"), IsOk());
  absl::StatusOr<std::vector<std::string>> names = reader.Take();
  ASSERT_THAT(names, IsOk());
  EXPECT_THAT(*names, ElementsAre("fork", "tilt"));

  ActionNamesReader gap("user \"ann\"", "user_actions");
  ASSERT_THAT(gap.Add(0, "fork"), IsOk());
  EXPECT_THAT(gap.Add(2, "tilt"),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("user \"ann\""),
                             HasSubstr("action 1 has no name in "
                                       "user_actions"))));
  ActionNamesReader late("pool 4", "pool_actions");
  EXPECT_THAT(late.Add(1, "tilt"),
              StatusIs(absl::StatusCode::kDataLoss,
                       HasSubstr("action 0 has no name in pool_actions")));
  ActionNamesReader none("pool 4", "pool_actions");
  EXPECT_THAT(none.Take(),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("pool 4"),
                             HasSubstr("no action names in pool_actions"))));
}

UserRecord ValidUser(const std::string& id) {
  UserRecord user;
  user.user_id = id;
  user.config.context_dim = 3;
  user.config.posthoc_dim = 2;
  return user;
}

TEST(StoreRowsTest, TheCheckReportKeepsDamageAsFindingsAndStopsOnOtherErrors) {
  CheckReportBuilder builder({"earlier finding"});
  EXPECT_THAT(builder.User(ValidUser("ann")), IsOk());
  // A user whose stored configuration does not validate.
  UserRecord odd = ValidUser("bob");
  odd.config.alpha = -1;
  EXPECT_THAT(builder.User(odd), IsOk());
  EXPECT_THAT(builder.User(absl::DataLossError("user \"cy\": bad prior")),
              IsOk());
  EXPECT_THAT(builder.Event(absl::OkStatus()), IsOk());
  EXPECT_THAT(builder.Event(absl::DataLossError("event 5: checksum")), IsOk());
  EXPECT_THAT(
      builder.Checkpoint(absl::DataLossError("the model checkpoint of ann")),
      IsOk());
  EXPECT_THAT(builder.Checkpoint(absl::OkStatus()), IsOk());
  // Anything but damage means the check could not run: returned as is.
  EXPECT_THAT(builder.Event(absl::UnavailableError("server gone")),
              StatusIs(absl::StatusCode::kUnavailable, "server gone"));
  EXPECT_THAT(builder.User(absl::InternalError("bug")),
              StatusIs(absl::StatusCode::kInternal, "bug"));

  const StoreCheckReport report = builder.Take();
  EXPECT_EQ(report.users_checked, 4);
  EXPECT_EQ(report.events_checked, 3);
  ASSERT_EQ(report.findings.size(), 5u);
  EXPECT_EQ(report.findings[0], "earlier finding");
  EXPECT_THAT(report.findings[1],
              AllOf(HasSubstr("user \"bob\""), HasSubstr("alpha")));
  EXPECT_EQ(report.findings[2], "user \"cy\": bad prior");
  EXPECT_EQ(report.findings[3], "event 5: checksum");
  EXPECT_THAT(report.findings[4],
              AllOf(HasSubstr("the model checkpoint of ann"),
                    HasSubstr("rebuilds that model from the log")));
}

TEST(StoreRowsTest, TheCheckReportKeepsAtMostOneHundredFindings) {
  CheckReportBuilder builder;
  for (int i = 0; i < 150; ++i) {
    ASSERT_THAT(builder.Event(absl::DataLossError(absl::StrCat("event ", i))),
                IsOk());
  }
  const StoreCheckReport report = builder.Take();
  EXPECT_EQ(report.events_checked, 150);
  ASSERT_EQ(report.findings.size(), 100u);
  EXPECT_EQ(report.findings.front(), "event 0");
  EXPECT_EQ(report.findings.back(), "event 99");
}

// Rows of real SQLite statements over literal values, read as the stores
// read theirs.
class StoreRowsSqliteTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(":memory:", &db), SQLITE_OK);
    db_.reset(db);
  }

  static std::string Hex(absl::string_view bytes) {
    return absl::StrCat("x'", absl::BytesToHexString(bytes), "'");
  }

  // An event row (the stores' kEventColumns order) with these values; the
  // checksums are computed here from what the row holds.
  std::string EventSql(bool completed, const std::string& posthoc_sql) {
    const std::string context = EncodeDoubles({0.5, -1.0});
    const int64_t selection =
        SelectionChecksum("ann", "lunch", "pea", context, 2, 0.25, 1000);
    const int64_t outcome =
        OutcomeChecksum(0.75, EncodeDoubles({3.0}), 1.5, 4, 2000);
    return absl::StrCat("SELECT 7, 'ann', 'lunch', 'pea', ", Hex(context),
                        ", 2, 0.25, 1000, ", completed ? 1 : 0, ", 0.75, ",
                        posthoc_sql, ", 1.5, 4, 2000, ", selection, ", ",
                        completed ? absl::StrCat(outcome) : "NULL");
  }

  absl::StatusOr<EventRecord> ReadEvent(const std::string& sql) {
    absl::StatusOr<sqlite::Statement> st =
        sqlite::Statement::Prepare(db_.get(), sql, "test");
    if (!st.ok()) return st.status();
    absl::StatusOr<bool> row = st->Step();
    EXPECT_TRUE(row.ok() && *row) << row.status();
    return ReadEventRow(*st);
  }

  std::unique_ptr<sqlite3, sqlite::SqliteCloser> db_;
};

TEST_F(StoreRowsSqliteTest, AnEventRowIsReadWithBothChecksumsChecked) {
  absl::StatusOr<EventRecord> event =
      ReadEvent(EventSql(true, Hex(EncodeDoubles({3.0}))));
  ASSERT_THAT(event, IsOk());
  EXPECT_EQ(event->event_id, 7);
  EXPECT_EQ(event->user_id, "ann");
  EXPECT_EQ(event->meal_id, "lunch");
  EXPECT_EQ(event->item_label, "pea");
  EXPECT_THAT(event->context, ElementsAre(0.5, -1.0));
  EXPECT_EQ(event->action, 2);
  EXPECT_EQ(event->propensity, 0.25);
  EXPECT_EQ(event->selected_at, absl::FromUnixMicros(1000));
  EXPECT_TRUE(event->completed);
  EXPECT_EQ(event->loss, 0.75);
  EXPECT_THAT(event->posthoc, ElementsAre(3.0));
  EXPECT_EQ(event->weight, 1.5);
  EXPECT_EQ(event->model_version, 4);
  EXPECT_EQ(event->updated_at, absl::FromUnixMicros(2000));

  // A pending event: its outcome columns are not read.
  absl::StatusOr<EventRecord> pending = ReadEvent(EventSql(false, "NULL"));
  ASSERT_THAT(pending, IsOk());
  EXPECT_FALSE(pending->completed);
  EXPECT_EQ(pending->model_version, 0);
  EXPECT_TRUE(pending->posthoc.empty());
}

TEST_F(StoreRowsSqliteTest, AnAlteredOrIncompleteEventRowIsDataLossNamingIt) {
  // Another post hoc vector than the outcome checksum covers.
  EXPECT_THAT(ReadEvent(EventSql(true, Hex(EncodeDoubles({3.5})))),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("event 7 of user \"ann\""),
                             HasSubstr("its outcome does not match"))));
  // A completed event without its outcome checksum.
  std::string sql = EventSql(true, Hex(EncodeDoubles({3.0})));
  sql = sql.substr(0, sql.rfind(',')) + ", NULL";
  EXPECT_THAT(ReadEvent(sql),
              StatusIs(absl::StatusCode::kDataLoss, HasSubstr("its outcome")));
  // Another item label than the selection checksum covers.
  sql = EventSql(false, "NULL");
  sql.replace(sql.find("'pea'"), 5, "'bean'");
  EXPECT_THAT(ReadEvent(sql),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("event 7"),
                             HasSubstr("its selection does not match"))));
}

TEST_F(StoreRowsSqliteTest, AUserRowWithAPriorThatDoesNotFitIsDataLoss) {
  PopulationPrior prior;
  prior.pool_version = 1;
  prior.rounds = 2;
  prior.context_msn = 1;
  prior.posthoc_msn = 1;
  prior.theta0 = {{1, 2}, {3, 4}};
  prior.phi0 = {{5}, {6}};
  auto read = [&](int64_t context_dim, const std::string& prior_sql,
                  int learner = 1) -> absl::StatusOr<UserRecord> {
    const std::string sql =
        absl::StrCat("SELECT 'ann', ", learner, ", 1, 0.5, 10.0, 1.0, 0.1, 1, ",
                     context_dim, ", 1, -1, 1000, 3, 1, ", prior_sql, ", 0.2");
    absl::StatusOr<sqlite::Statement> st =
        sqlite::Statement::Prepare(db_.get(), sql, "test");
    if (!st.ok()) return st.status();
    EXPECT_TRUE(*st->Step());
    return ReadUserRow(*st,
                       [](const std::string& user_id, const std::string& what)
                           -> absl::StatusOr<std::vector<std::string>> {
                         EXPECT_EQ(user_id, "ann");
                         EXPECT_EQ(what, "user \"ann\"");
                         return std::vector<std::string>{"fork", "tilt"};
                       });
  };
  absl::StatusOr<UserRecord> user = read(2, Hex(EncodePrior(prior)));
  ASSERT_THAT(user, IsOk());
  EXPECT_EQ(user->config.context_dim, 2);
  EXPECT_EQ(user->config.seed, std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(user->config.prior.theta0, prior.theta0);
  EXPECT_EQ(user->config.phi_radius, 0.2);
  EXPECT_TRUE(user->config.importance_weighting);
  EXPECT_EQ(user->model_version, 3);
  EXPECT_EQ(user->pending_events, 1);
  EXPECT_THAT(user->config.action_names, ElementsAre("fork", "tilt"));

  EXPECT_THAT(read(3, Hex(EncodePrior(prior))),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("user \"ann\""), HasSubstr("theta0"))));
  EXPECT_THAT(read(2, "x'0102'"),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("user \"ann\" prior"),
                             HasSubstr("not a multiple of 8"))));
  EXPECT_THAT(read(2, "NULL", 9), StatusIs(absl::StatusCode::kDataLoss,
                                           HasSubstr("unknown learner 9")));
  EXPECT_THAT(read(int64_t{1} << 40, "NULL"),
              StatusIs(absl::StatusCode::kDataLoss,
                       AllOf(HasSubstr("user \"ann\" context_dim"),
                             HasSubstr("out of range"))));
}

}  // namespace
}  // namespace bitewise::bandit::store_rows
