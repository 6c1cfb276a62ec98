// The checkpoint role of the store contract (checkpoint_store.h), on every
// backend.
#include "tests/bandit/store/store_test_fixture.h"

namespace bitewise::bandit::store_test {
namespace {

class CheckpointContractTest : public StoreContractTest {};
INSTANTIATE_TEST_SUITE_P(Stores, CheckpointContractTest, kAllBackends,
                         BackendName);

// An event altered on disk is DATA_LOSS naming it, for its selection and
// for its outcome, wherever it is read, so it is never learned from.
// A checkpoint larger than a chunk round-trips through several chunk
// transactions; the events after it are read from its version on; a damaged
// chunk is DATA_LOSS naming the user; a reset or a deleted user takes the
// checkpoint with it, and a checkpoint of a log that moved on is not kept.
TEST_P(CheckpointContractTest, CheckpointsRoundTripInChunksAndGoWithTheLog) {
  ASSERT_TRUE(store_->CreateUser(MakeUser("ann")).ok());
  std::vector<int64_t> ids;
  for (int i = 0; i < 5; ++i) {
    ids.push_back(MustAppend(MakeEvent("ann", "m", i)));
    MustComplete(ids.back());
  }
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  ModelCheckpoint checkpoint;
  checkpoint.model_version = 3;
  checkpoint.last_event_id = ids[2];
  checkpoint.created_at = absl::FromUnixMicros(1700000003000000);
  std::mt19937_64 rng(8);
  checkpoint.state.resize(2 * SqliteEventStore::kCheckpointChunkBytes + 12345);
  for (char& c : checkpoint.state) c = static_cast<char>(rng());
  ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok());
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "3");
  auto read = store_->GetCheckpoint("ann");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->model_version, 3);
  EXPECT_EQ(read->last_event_id, ids[2]);
  EXPECT_EQ(read->created_at, checkpoint.created_at);
  EXPECT_TRUE(read->state == checkpoint.state);
  auto after = store_->CompletedEventsFrom("ann", 3);
  ASSERT_TRUE(after.ok());
  ASSERT_EQ(after->size(), 3u);
  EXPECT_EQ((*after)[0].event_id, ids[2]);
  EXPECT_EQ((*after)[2].model_version, 5);
  // A newer one replaces it, and its chunks the old ones.
  checkpoint.model_version = 5;
  checkpoint.last_event_id = ids[4];
  checkpoint.state = "small";
  ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok());
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "1");
  EXPECT_EQ(store_->GetCheckpoint("ann")->state, "small");
  // Damaged bytes.
  Raw().Exec(absl::StrCat("UPDATE model_checkpoint_chunks SET data = ",
                          BlobLiteral("736D616C6C21")));
  auto damaged = store_->GetCheckpoint("ann");
  EXPECT_EQ(damaged.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(damaged.status().message(), HasSubstr("user ann"));
  // The full check finds it too, as a finding (the store is still usable).
  {
    absl::StatusOr<StoreCheckReport> check = store_->CheckStore();
    ASSERT_TRUE(check.ok()) << check.status();
    ASSERT_EQ(check->findings.size(), 1u);
    EXPECT_THAT(check->findings[0], HasSubstr("model checkpoint of user ann"));
  }
  // A checkpoint whose event is not at its version is not kept (nor its
  // chunks); the one in place stays until deleted.
  checkpoint.model_version = 4;
  checkpoint.last_event_id = ids[2];
  EXPECT_EQ(store_->PutCheckpoint("ann", checkpoint).code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "1");
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kDataLoss);  // the damaged version 5, still
  ASSERT_TRUE(store_->DeleteCheckpoint("ann").ok());
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  checkpoint.model_version = 5;
  // A new learner, reset and delete take it along.
  checkpoint.last_event_id = ids[4];
  ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok());
  ASSERT_TRUE(store_->SetLearner("ann", Learner::kPoLinUcb, 5).ok());
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  // A model of the old learner, written late, is not current.
  const absl::Status late = store_->PutCheckpoint("ann", checkpoint);
  EXPECT_EQ(late.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(late.message()), HasSubstr("another learner"));
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  checkpoint.learner = Learner::kPoLinUcb;
  ASSERT_TRUE(store_->PutCheckpoint("ann", checkpoint).ok());
  ASSERT_TRUE(store_->ResetUser("ann").ok());
  EXPECT_EQ(store_->GetCheckpoint("ann").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoint_chunks"), "0");
  ASSERT_TRUE(store_->CreateUser(MakeUser("bob")).ok());
  const int64_t bob_event = MustAppend(MakeEvent("bob", "m"));
  MustComplete(bob_event);
  checkpoint.model_version = 1;
  checkpoint.last_event_id = bob_event;
  checkpoint.learner = Learner::kPostHoc;
  ASSERT_TRUE(store_->PutCheckpoint("bob", checkpoint).ok());
  ASSERT_TRUE(store_->DeleteUser("bob").ok());
  EXPECT_EQ(Raw().Text("SELECT COUNT(*) FROM model_checkpoints"), "0");
  EXPECT_EQ(store_->PutCheckpoint("nobody", checkpoint).code(),
            absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace bitewise::bandit::store_test
