// Standalone driver for LLVMFuzzerTestOneInput when libFuzzer is not used: replays every
// file of the given corpus folders/files, then runs seeded random mutations of them
// (bit flips, byte replacements, truncation, insertion, splicing, integer overwrites).
// Any crash, sanitizer report or escaping exception fails the run.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace {

std::vector<std::uint8_t> ReadFile(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<std::uint8_t>((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
}

void Run(const std::vector<std::uint8_t>& input) {
  try {
    LLVMFuzzerTestOneInput(input.data(), input.size());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "uncaught exception escaped the fuzz target: %s\n", e.what());
    std::abort();
  }
}

std::vector<std::uint8_t> Mutate(std::vector<std::uint8_t> s, std::mt19937_64& rng,
                                 const std::vector<std::vector<std::uint8_t>>& pool) {
  const int n_mut = 1 + static_cast<int>(rng() % 4);
  for (int m = 0; m < n_mut; ++m) {
    const std::size_t size = s.size();
    switch (rng() % 7) {
      case 0:  // bit flip
        if (size) s[rng() % size] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
        break;
      case 1:  // random byte
        if (size) s[rng() % size] = static_cast<std::uint8_t>(rng());
        break;
      case 2:  // truncate
        if (size) s.resize(rng() % size);
        break;
      case 3: {  // insert random bytes
        const std::size_t pos = size ? rng() % (size + 1) : 0;
        const std::size_t len = 1 + rng() % 16;
        std::vector<std::uint8_t> ins(len);
        for (auto& b : ins) b = static_cast<std::uint8_t>(rng());
        s.insert(s.begin() + static_cast<std::ptrdiff_t>(pos), ins.begin(), ins.end());
        break;
      }
      case 4: {  // overwrite with an interesting ASCII number
        static const char* kNums[] = {"0",   "-1",  "4294967295", "99999999999",
                                      "nan", "inf", "1e308",      "-2147483648",
                                      "3",   "255", "65536"};
        const char* num = kNums[rng() % (sizeof(kNums) / sizeof(kNums[0]))];
        const std::size_t len = std::strlen(num);
        if (size >= len) {
          const std::size_t pos = rng() % (size - len + 1);
          std::memcpy(s.data() + pos, num, len);
        }
        break;
      }
      case 5: {  // splice with another corpus entry
        if (!pool.empty()) {
          const auto& other = pool[rng() % pool.size()];
          if (!other.empty() && size) {
            const std::size_t cut = rng() % size;
            const std::size_t from = rng() % other.size();
            s.resize(cut);
            s.insert(s.end(), other.begin() + static_cast<std::ptrdiff_t>(from), other.end());
          }
        }
        break;
      }
      default: {  // overwrite 4 bytes with an extreme binary integer
        static const std::uint32_t kInts[] = {0u, 0xffffffffu, 0x7fffffffu, 0x80000000u, 1u << 30};
        if (size >= 4) {
          const std::uint32_t v = kInts[rng() % 5];
          std::memcpy(s.data() + rng() % (size - 3), &v, 4);
        }
        break;
      }
    }
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  long iterations = 1000;
  unsigned long long seed = 1;
  std::vector<std::vector<std::uint8_t>> corpus;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--iterations" && i + 1 < argc) {
      iterations = std::atol(argv[++i]);
    } else if (arg == "--seed" && i + 1 < argc) {
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else {
      const std::filesystem::path p(arg);
      if (std::filesystem::is_directory(p)) {
        std::vector<std::filesystem::path> files;
        for (const auto& e : std::filesystem::directory_iterator(p)) {
          if (e.is_regular_file()) files.push_back(e.path());
        }
        std::sort(files.begin(), files.end());
        for (const auto& f : files) corpus.push_back(ReadFile(f));
      } else if (std::filesystem::is_regular_file(p)) {
        corpus.push_back(ReadFile(p));
      } else {
        std::fprintf(stderr, "fuzz driver: corpus path '%s' does not exist\n", arg.c_str());
        return 2;
      }
    }
  }
  if (corpus.empty()) corpus.push_back({});
  for (const auto& c : corpus) Run(c);
  std::mt19937_64 rng(seed);
  for (long it = 0; it < iterations; ++it) {
    const auto& base = corpus[rng() % corpus.size()];
    Run(Mutate(base, rng, corpus));
  }
  std::printf("fuzz driver: %zu corpus inputs + %ld mutations, no findings\n", corpus.size(),
              iterations);
  return 0;
}
