#include "clients/meal/trace_recording.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "absl/types/span.h"
#include "services/domain/trace_csv.h"

namespace bitewise::meals {
namespace {

constexpr char kTracesFile[] = "traces.csv";
constexpr char kBitesFile[] = "bites.csv";
constexpr char kBitesHeader[] =
    "trace,time_utc,user,meal,event_id,food,label,action,outcome,haptic,"
    "p_hard,p_medium,p_soft,p_hard_skin,familiarity,unfamiliar,"
    "force_limit_reached";
// The headers of earlier releases: before the force-limit column, and before
// the familiarity columns. Such a file is appended to in its own format, so
// that it stays one table for the lab's spreadsheet and the trainer's
// --labels.
constexpr char kBitesHeaderBeforeForceLimit[] =
    "trace,time_utc,user,meal,event_id,food,label,action,outcome,haptic,"
    "p_hard,p_medium,p_soft,p_hard_skin,familiarity,unfamiliar";
constexpr char kBitesHeaderBeforeFamiliarity[] =
    "trace,time_utc,user,meal,event_id,food,label,action,outcome,haptic,"
    "p_hard,p_medium,p_soft,p_hard_skin";

std::string Errno(const std::string& what, const std::string& path) {
  return absl::StrCat(what, " ", path, ": ", std::strerror(errno));
}

// Reads up to the last 64 KiB of `fd` (an open file of `size` bytes), or
// all of it.
std::string Tail(int fd, off_t size, bool whole = false) {
  const off_t start = !whole && size > 65536 ? size - 65536 : 0;
  std::string text(static_cast<size_t>(size - start), '\0');
  const ssize_t n = pread(fd, text.data(), text.size(), start);
  text.resize(n > 0 ? static_cast<size_t>(n) : 0);
  return text;
}

// Opens `path` for appending, writing `headers[0]` if the file is new or
// empty and otherwise checking that its first line is one of `headers`.
// Sets `*header` to the index of the file's header and `*last_id` to the
// first field of the last complete row, if it is a number. A last row cut
// short is cut off.
absl::StatusOr<int> OpenCsv(const std::string& path,
                            absl::Span<const absl::string_view> headers,
                            bool largest_id_anywhere, int* header,
                            int64_t* last_id) {
  const int fd =
      open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return absl::InternalError(Errno("cannot open", path));
  struct stat st;
  if (fstat(fd, &st) != 0) {
    close(fd);
    return absl::InternalError(Errno("cannot stat", path));
  }
  *header = 0;
  *last_id = -1;
  if (st.st_size == 0) {
    const std::string line = absl::StrCat(headers[0], "\n");
    if (write(fd, line.data(), line.size()) !=
            static_cast<ssize_t>(line.size()) ||
        fsync(fd) != 0) {
      close(fd);
      return absl::InternalError(Errno("cannot write", path));
    }
    return fd;
  }
  size_t longest = 0;
  for (absl::string_view h : headers) longest = std::max(longest, h.size());
  std::string first(longest + 2, '\0');  // the header, "\r\n" at most
  const ssize_t n = pread(fd, first.data(), first.size(), 0);
  first.resize(n > 0 ? static_cast<size_t>(n) : 0);
  const size_t end = first.find('\n');
  // A spreadsheet may have saved it with CRLF line ends.
  const auto found =
      end == std::string::npos
          ? headers.end()
          : std::find(headers.begin(), headers.end(),
                      absl::StripSuffix(absl::string_view(first).substr(0, end),
                                        "\r"));
  if (found == headers.end()) {
    close(fd);
    std::string message = absl::StrCat(
        path, " is not a bitewise recording: its first line is not \"",
        headers[0], "\"");
    for (size_t i = 1; i < headers.size(); ++i) {
      absl::StrAppend(&message, " nor \"", headers[i],
                      "\" (an earlier release's)");
    }
    return absl::InvalidArgumentError(message);
  }
  *header = static_cast<int>(found - headers.begin());
  std::string tail = Tail(fd, st.st_size);
  if (!tail.empty() && tail.back() != '\n') {
    const size_t keep = tail.rfind('\n') + 1;
    const absl::string_view last = absl::string_view(tail).substr(keep);
    const absl::string_view columns = headers[*header];
    if (std::count(last.begin(), last.end(), ',') ==
        std::count(columns.begin(), columns.end(), ',')) {
      // A whole row without its newline (a spreadsheet may save so): it is
      // ended, not dropped.
      if (write(fd, "\n", 1) != 1 || fsync(fd) != 0) {
        close(fd);
        return absl::InternalError(Errno("cannot repair", path));
      }
      tail.push_back('\n');
    } else {
      // A row cut short (a power loss between write and fsync): dropped.
      if (ftruncate(fd, st.st_size - static_cast<off_t>(tail.size() - keep)) !=
          0) {
        close(fd);
        return absl::InternalError(Errno("cannot repair", path));
      }
      tail.erase(keep);
    }
  }
  // traces.csv is in id order: its last row has the largest. bites.csv may
  // have been sorted or extended in a spreadsheet: all of it is read.
  std::string text;
  if (largest_id_anywhere) {
    if (fstat(fd, &st) != 0) {
      close(fd);
      return absl::InternalError(Errno("cannot stat", path));
    }
    text = Tail(fd, st.st_size, /*whole=*/true);
  } else {
    const size_t last_row =
        tail.size() < 2 ? std::string::npos : tail.rfind('\n', tail.size() - 2);
    text = tail.substr(last_row == std::string::npos ? 0 : last_row + 1);
  }
  for (absl::string_view line : absl::StrSplit(text, '\n', absl::SkipEmpty())) {
    int64_t id;
    if (absl::SimpleAtoi(line.substr(0, line.find(',')), &id) && id >= 0) {
      *last_id = std::max(*last_id, id);
    }
  }
  return fd;
}

// Cuts off traces.csv's last rows whose trace id is above `last_bite`: a
// trace whose bites.csv row was never written (a crash between the two
// writes) has no outcome, label or answer, and half of it may be missing.
// The rows of one trace are together at the end, so the file is read
// backwards a block at a time until a row of an earlier trace.
absl::Status CutTracesWithoutABite(int fd, const std::string& path,
                                   int64_t last_bite) {
  struct stat st;
  if (fstat(fd, &st) != 0)
    return absl::InternalError(Errno("cannot stat", path));
  off_t cut = st.st_size;
  off_t pos = st.st_size;
  std::string buffer;  // the file from `pos` to its end, read so far
  bool done = false;
  while (!done && pos > 0) {
    const off_t start = pos > 65536 ? pos - 65536 : 0;
    std::string block(static_cast<size_t>(pos - start), '\0');
    if (pread(fd, block.data(), block.size(), start) !=
        static_cast<ssize_t>(block.size())) {
      return absl::InternalError(Errno("cannot read", path));
    }
    buffer.insert(0, block);
    pos = start;
    // Whole lines of `buffer` before `cut`, last first: [begin, end) with
    // its newline at end - 1 (the file ends with one: OpenCsv cut off a row
    // cut short). The first line is whole only at the file's start.
    size_t end = static_cast<size_t>(cut - pos);
    while (end > 0) {
      const size_t newline =
          end >= 2 ? buffer.rfind('\n', end - 2) : std::string::npos;
      if (newline == std::string::npos && pos > 0) break;  // read more
      const size_t begin = newline == std::string::npos ? 0 : newline + 1;
      const absl::string_view line =
          absl::string_view(buffer).substr(begin, end - 1 - begin);
      int64_t id;
      if (!absl::SimpleAtoi(line.substr(0, line.find(',')), &id) ||
          id <= last_bite) {
        done = true;
        break;
      }
      cut = pos + static_cast<off_t>(begin);
      end = begin;
    }
    if (end == 0) done = true;
  }
  if (cut < st.st_size && (ftruncate(fd, cut) != 0 || fsync(fd) != 0)) {
    return absl::InternalError(Errno("cannot repair", path));
  }
  return absl::OkStatus();
}

// A field of bites.csv: ids are checked by the services (no commas), but
// food names and outcomes come from elsewhere.
std::string Field(const std::string& text) {
  std::string out = text;
  for (char& c : out) {
    if (c == ',' || c == '\n' || c == '\r') c = ' ';
  }
  return out;
}

bool WriteAll(int fd, const std::string& text) {
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return fdatasync(fd) == 0;
}

}  // namespace

absl::StatusOr<std::unique_ptr<TraceRecording>> TraceRecording::Open(
    const std::string& dir) {
  if (dir.empty()) {
    return absl::InvalidArgumentError("the recording directory is empty");
  }
  if (mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST) {
    return absl::InternalError(Errno("cannot create the directory", dir));
  }
  // One process records into a directory at a time, and its lock is taken
  // before anything is read or repaired: two would give two bites one id
  // (the trainer's --labels then refuses the file), and one would cut off
  // the other's row as it is being written.
  const int lock_fd = open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (lock_fd < 0) return absl::InternalError(Errno("cannot open", dir));
  if (flock(lock_fd, LOCK_EX | LOCK_NB) != 0) {
    close(lock_fd);
    return absl::FailedPreconditionError(absl::StrCat(
        "the recording in ", dir,
        " is open in another process (an orchestrator or console recording "
        "there): record into another directory"));
  }
  int64_t last_trace = -1, last_bite = -1;
  int traces_header = 0, bites_header = 0;
  const absl::string_view trace_headers[] = {domain::kTraceCsvHeader};
  absl::StatusOr<int> traces =
      OpenCsv(absl::StrCat(dir, "/", kTracesFile), trace_headers,
              /*largest_id_anywhere=*/false, &traces_header, &last_trace);
  if (!traces.ok()) {
    close(lock_fd);
    return traces.status();
  }
  const absl::string_view bite_headers[] = {kBitesHeader,
                                            kBitesHeaderBeforeForceLimit,
                                            kBitesHeaderBeforeFamiliarity};
  absl::StatusOr<int> bites =
      OpenCsv(absl::StrCat(dir, "/", kBitesFile), bite_headers,
              /*largest_id_anywhere=*/true, &bites_header, &last_bite);
  if (!bites.ok()) {
    close(*traces);
    close(lock_fd);
    return bites.status();
  }
  // One process writes here, a bite at a time, its trace rows first: only
  // the newest bite, the one after the largest id in bites.csv, can have
  // trace rows without its bites.csv row. Anything else (bites.csv edited
  // so that bites are missing) is not repaired by cutting traces off: it
  // is refused.
  std::string repaired;
  if (last_trace > last_bite) {
    absl::Status cut =
        last_trace == last_bite + 1
            ? CutTracesWithoutABite(
                  *traces, absl::StrCat(dir, "/", kTracesFile), last_bite)
            : absl::FailedPreconditionError(absl::StrCat(
                  dir, "/", kTracesFile, " ends with trace ", last_trace,
                  " but ", dir, "/", kBitesFile, " has ",
                  last_bite < 0 ? std::string("no bite")
                                : absl::StrCat("bites up to ", last_bite),
                  ": fix ", kBitesFile,
                  " (a spreadsheet may have dropped or changed rows); ",
                  kTracesFile, " was left as it is"));
    if (!cut.ok()) {
      close(*traces);
      close(*bites);
      close(lock_fd);
      return cut;
    }
    repaired = absl::StrCat("cut off trace ", last_trace, "'s rows from ", dir,
                            "/", kTracesFile,
                            ": its bites.csv row was never written (the "
                            "recording stopped between the two)");
    last_trace = last_bite;
  }
  std::unique_ptr<TraceRecording> recording(new TraceRecording(
      dir, lock_fd, *traces, *bites, std::max(last_trace, last_bite) + 1,
      /*records_familiarity=*/bites_header <= 1,
      /*records_force_limit=*/bites_header == 0));
  if (!repaired.empty()) {
    recording->note_ = recording->note_.empty()
                           ? repaired
                           : absl::StrCat(recording->note_, "; ", repaired);
  }
  return recording;
}

TraceRecording::TraceRecording(std::string dir, int lock_fd, int traces_fd,
                               int bites_fd, int64_t next_id,
                               bool records_familiarity,
                               bool records_force_limit)
    : dir_(std::move(dir)),
      lock_fd_(lock_fd),
      records_familiarity_(records_familiarity),
      records_force_limit_(records_force_limit),
      note_(records_force_limit ? ""
            : records_familiarity
                ? absl::StrCat(dir_, "/", kBitesFile,
                               " predates the force_limit_reached column (an "
                               "earlier release started it), so whether the "
                               "force limit cut a trace short is not "
                               "recorded in this directory; record into a "
                               "new directory to have it")
                : absl::StrCat(dir_, "/", kBitesFile,
                               " predates the familiarity columns (an "
                               "earlier release started it), so familiarity "
                               "and the force limit are not recorded in this "
                               "directory; record into a new directory to "
                               "have them")),
      traces_fd_(traces_fd),
      bites_fd_(bites_fd),
      next_id_(next_id) {}

TraceRecording::~TraceRecording() {
  absl::MutexLock lock(&mu_);
  close(traces_fd_);
  close(bites_fd_);
  close(lock_fd_);  // the directory's lock goes last
}

int64_t TraceRecording::recorded() const {
  absl::MutexLock lock(&mu_);
  return recorded_;
}

absl::StatusOr<std::string> TraceRecording::Record(
    const RecordedBite& bite,
    const google::protobuf::RepeatedPtrField<v1::WrenchSample>& trace) {
  if (trace.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("event ", bite.event_id, ": the trace is empty"));
  }
  const char* label = bite.label.has_value()
                          ? domain::HapticClassName(*bite.label)
                          : domain::kUnlabelled;
  absl::MutexLock lock(&mu_);
  if (broken_) {
    return absl::InternalError(absl::StrCat(
        "the recording in ", dir_, " stopped at an earlier write error"));
  }
  const std::string id = absl::StrCat(next_id_);
  std::string rows;
  rows.reserve(static_cast<size_t>(trace.size()) * 120);
  for (const v1::WrenchSample& s : trace) {
    domain::AppendTraceCsvRow(
        &rows, id, label, s.t_s(),
        {s.fx_n(), s.fy_n(), s.fz_n(), s.tx_nm(), s.ty_nm(), s.tz_nm()});
  }
  std::string row = absl::StrCat(
      id, ",",
      absl::FormatTime("%Y-%m-%dT%H:%M:%E3SZ", absl::Now(),
                       absl::UTCTimeZone()),
      ",", Field(bite.user_id), ",", Field(bite.meal_id), ",",
      Field(bite.event_id), ",", Field(bite.food), ",", label, ",",
      Field(bite.action), ",", Field(bite.outcome), ",",
      bite.haptic.has_value() ? domain::HapticClassName(*bite.haptic)
      : bite.no_contact       ? "no contact"
                              : "none");
  for (int k = 0; k < domain::kHapticClasses; ++k) {
    if (bite.haptic.has_value() &&
        static_cast<int>(bite.probabilities.size()) == domain::kHapticClasses) {
      absl::StrAppend(&row, ",",
                      absl::StrFormat("%.6f", bite.probabilities[k]));
    } else {
      absl::StrAppend(&row, ",");
    }
  }
  if (records_familiarity_) {
    if (bite.familiarity.has_value() && std::isfinite(*bite.familiarity)) {
      absl::StrAppend(&row, ",", absl::StrFormat("%.6f", *bite.familiarity),
                      ",", bite.unfamiliar ? "1" : "0");
    } else {
      absl::StrAppend(&row, ",,");
    }
  }
  if (records_force_limit_) {
    absl::StrAppend(&row, ",", bite.force_limit_reached ? "1" : "0");
  }
  row.push_back('\n');
  // A bite is both files' rows or neither's: a write that fails part way
  // (a full disk) is cut off again in both.
  struct stat traces_st, bites_st;
  if (fstat(traces_fd_, &traces_st) != 0 || fstat(bites_fd_, &bites_st) != 0) {
    broken_ = true;
    return absl::InternalError(Errno("cannot stat the recording in", dir_));
  }
  auto undo = [&](const char* file) {
    const std::string message =
        Errno("cannot write", absl::StrCat(dir_, "/", file));
    broken_ = true;
    if (ftruncate(traces_fd_, traces_st.st_size) != 0 ||
        ftruncate(bites_fd_, bites_st.st_size) != 0) {
      return absl::InternalError(
          absl::StrCat(message,
                       "; and cannot cut the bite's rows off again (the next "
                       "open of the recording does)"));
    }
    fdatasync(traces_fd_);
    fdatasync(bites_fd_);
    return absl::InternalError(
        absl::StrCat(message, "; this bite's rows were cut off again"));
  };
  if (!WriteAll(traces_fd_, rows)) return undo(kTracesFile);
  if (!WriteAll(bites_fd_, row)) return undo(kBitesFile);
  ++next_id_;
  ++recorded_;
  return id;
}

}  // namespace bitewise::meals
