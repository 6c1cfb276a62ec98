#include "experiments/idx.h"

#include <fstream>
#include <string>

#include "gtest/gtest.h"

namespace bitewise::experiments {
namespace {

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/" + name;
}

TEST(IdxTest, ImagesAndLabelsRoundTrip) {
  IdxImages images;
  images.count = 3;
  images.rows = 2;
  images.cols = 4;
  for (int i = 0; i < 24; ++i) images.pixels.push_back(i * 10 + 5);
  const std::string image_path = TempPath("idx_images");
  const std::string label_path = TempPath("idx_labels");
  ASSERT_TRUE(WriteIdxImages(image_path, images).ok());
  ASSERT_TRUE(WriteIdxLabels(label_path, {7, 0, 9}).ok());

  auto read = ReadIdxImages(image_path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->count, 3);
  EXPECT_EQ(read->rows, 2);
  EXPECT_EQ(read->cols, 4);
  EXPECT_EQ(read->pixels, images.pixels);
  auto labels = ReadIdxLabels(label_path);
  ASSERT_TRUE(labels.ok()) << labels.status();
  EXPECT_EQ(*labels, (std::vector<uint8_t>{7, 0, 9}));

  // The header is big-endian, as in the MNIST distribution.
  std::ifstream in(image_path, std::ios::binary);
  char head[8];
  in.read(head, 8);
  EXPECT_EQ(std::string(head, 8), std::string("\0\0\x08\x03\0\0\0\x03", 8));
}

TEST(IdxTest, RejectsTruncatedAndMislabelledFiles) {
  IdxImages images;
  images.count = 2;
  images.rows = 2;
  images.cols = 2;
  images.pixels.assign(8, 1);
  const std::string path = TempPath("idx_truncated");
  ASSERT_TRUE(WriteIdxImages(path, images).ok());
  std::ofstream(path, std::ios::binary | std::ios::app) << "x";
  EXPECT_EQ(ReadIdxImages(path).status().code(), absl::StatusCode::kDataLoss);

  const std::string labels = TempPath("idx_labels_as_images");
  ASSERT_TRUE(WriteIdxLabels(labels, {1, 2}).ok());
  EXPECT_EQ(ReadIdxImages(labels).status().code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(ReadIdxLabels(path).status().code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(ReadIdxLabels(TempPath("no_such_file")).status().code(),
            absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace bitewise::experiments
