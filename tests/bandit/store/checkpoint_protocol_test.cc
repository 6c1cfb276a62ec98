// The checkpoint protocol (checkpoint_protocol.h) on every backend: what is
// refused before anything is written, where chunks are cut, chunks that
// go missing or out of order, and a newer checkpoint never replaced by an
// older one.
#include "tests/bandit/store/store_test_fixture.h"

namespace bitewise::bandit::store_test {
namespace {

class CheckpointProtocolTest : public StoreContractTest {
 protected:
  // A user with `n` completed events; their ids.
  std::vector<int64_t> UserWithEvents(const std::string& user_id, int n) {
    EXPECT_TRUE(store_->CreateUser(MakeUser(user_id)).ok());
    std::vector<int64_t> ids;
    for (int i = 0; i < n; ++i) {
      ids.push_back(MustAppend(MakeEvent(user_id, "m", i)));
      MustComplete(ids.back());
    }
    return ids;
  }

  static ModelCheckpoint Checkpoint(int64_t version, int64_t event_id,
                                    size_t bytes, char fill) {
    ModelCheckpoint checkpoint;
    checkpoint.model_version = version;
    checkpoint.last_event_id = event_id;
    checkpoint.created_at = absl::FromUnixMicros(1700000005000000);
    checkpoint.state.resize(bytes);
    for (size_t i = 0; i < bytes; ++i) {
      checkpoint.state[i] = static_cast<char>(fill + i % 7);
    }
    return checkpoint;
  }

  std::string Chunks() {
    return Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks");
  }
};
INSTANTIATE_TEST_SUITE_P(Stores, CheckpointProtocolTest, kAllBackends,
                         BackendName);

constexpr size_t kChunk = SqliteEventStore::kCheckpointChunkBytes;
static_assert(kChunk == PostgresEventStore::kCheckpointChunkBytes);

TEST_P(CheckpointProtocolTest, AnInvalidCheckpointIsRefusedBeforeAnyWrite) {
  const std::vector<int64_t> ids = UserWithEvents("ann", 1);
  for (const ModelCheckpoint& bad :
       {Checkpoint(0, ids[0], 10, 'a'), Checkpoint(-1, ids[0], 10, 'a'),
        Checkpoint(1, ids[0], 0, 'a')}) {
    const absl::Status status = store_->PutCheckpoint("ann", bad);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_THAT(status.message(), HasSubstr("model_version > 0 and a state"));
  }
  EXPECT_EQ(Chunks(), "0");
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
}

TEST_P(CheckpointProtocolTest, ChunksAreCutAtTheChunkSize) {
  const std::vector<int64_t> ids = UserWithEvents("ann", 3);
  struct Case {
    size_t bytes;
    const char* chunks;
  };
  const Case cases[] = {{1, "1"}, {kChunk, "1"}, {kChunk + 1, "2"}};
  for (int v = 1; v <= 3; ++v) {
    const Case& c = cases[v - 1];
    // Each one newer than the last, so each replaces it.
    const ModelCheckpoint checkpoint =
        Checkpoint(v, ids[v - 1], c.bytes, static_cast<char>('a' + v));
    ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok()) << c.bytes;
    EXPECT_EQ(Chunks(), c.chunks) << c.bytes;
    EXPECT_EQ(Raw().Text("SELECT SUM(LENGTH(data)) FROM "
                         "model_checkpoint_chunks"),
              absl::StrCat(c.bytes));
    absl::StatusOr<ModelCheckpoint> read = store_->GetCheckpoint("ann");
    ASSERT_TRUE(read.ok()) << read.status();
    EXPECT_EQ(read->model_version, v);
    EXPECT_TRUE(read->state == checkpoint.state) << c.bytes;
  }
  // Exactly two chunks' worth, on a user of its own.
  const std::vector<int64_t> bob = UserWithEvents("bob", 1);
  ASSERT_TRUE(
      store_->PutCheckpoint("bob", Checkpoint(1, bob[0], 2 * kChunk, 'z'))
          .ok());
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks WHERE "
                       "user_id = 'bob'"),
            "2");
  EXPECT_EQ(store_->GetCheckpoint("bob")->state.size(), 2 * kChunk);
}

TEST_P(CheckpointProtocolTest, AMissingChunkIsDataLossNamingTheUser) {
  const std::vector<int64_t> ids = UserWithEvents("ann", 3);
  ASSERT_TRUE(
      store_->PutCheckpoint("ann", Checkpoint(3, ids[2], 2 * kChunk + 5, 'q'))
          .ok());
  ASSERT_EQ(Chunks(), "3");
  Raw().Exec("DELETE FROM model_checkpoint_chunks WHERE seq = 1");
  const absl::Status missing = store_->GetCheckpoint("ann").status();
  EXPECT_EQ(missing.code(), absl::StatusCode::kDataLoss) << missing;
  EXPECT_THAT(missing.message(),
              HasSubstr("the model checkpoint of user ann at model version 3 "
                        "is damaged"));
  EXPECT_THAT(missing.message(), HasSubstr("in 1 of 3 chunks"));
}

TEST_P(CheckpointProtocolTest, ChunksOutOfOrderOrTooManyAreDataLoss) {
  const std::vector<int64_t> ids = UserWithEvents("ann", 3);
  ASSERT_TRUE(
      store_->PutCheckpoint("ann", Checkpoint(3, ids[2], 2 * kChunk + 5, 'q'))
          .ok());
  // The last chunk moved past a gap.
  Raw().Exec("UPDATE model_checkpoint_chunks SET seq = 7 WHERE seq = 2");
  absl::Status status = store_->GetCheckpoint("ann").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss) << status;
  EXPECT_THAT(status.message(), HasSubstr("in 2 of 3 chunks"));
  // Back in place it reads again, so nothing else was wrong.
  Raw().Exec("UPDATE model_checkpoint_chunks SET seq = 2 WHERE seq = 7");
  ASSERT_TRUE(store_->GetCheckpoint("ann").ok());
  // No first chunk.
  Raw().Exec("UPDATE model_checkpoint_chunks SET seq = 9 WHERE seq = 0");
  status = store_->GetCheckpoint("ann").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss) << status;
  EXPECT_THAT(status.message(), HasSubstr("in 0 of 3 chunks"));
  Raw().Exec("UPDATE model_checkpoint_chunks SET seq = 0 WHERE seq = 9");
  // A chunk more than the header counts.
  Raw().Exec("UPDATE model_checkpoints SET chunks = 2");
  status = store_->GetCheckpoint("ann").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss) << status;
  EXPECT_THAT(status.message(), HasSubstr("user ann"));
  EXPECT_THAT(status.message(), HasSubstr("in 2 of 2 chunks"));
}

TEST_P(CheckpointProtocolTest, AnOlderCheckpointNeverReplacesANewerOne) {
  const std::vector<int64_t> ids = UserWithEvents("ann", 5);
  const ModelCheckpoint newer = Checkpoint(5, ids[4], kChunk + 3, 'n');
  ASSERT_TRUE(store_->PutCheckpoint("ann", newer).ok());
  // A slower writer's checkpoint of version 3 arrives after it.
  // It is answered OK: a newer checkpoint stands in for it.
  EXPECT_TRUE(
      store_->PutCheckpoint("ann", Checkpoint(3, ids[2], 3 * kChunk, 'o'))
          .ok());
  absl::StatusOr<ModelCheckpoint> read = store_->GetCheckpoint("ann");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->model_version, 5);
  EXPECT_TRUE(read->state == newer.state);
  // The older write's chunks did not stay behind.
  EXPECT_EQ(Chunks(), "2");
}

}  // namespace
}  // namespace bitewise::bandit::store_test
