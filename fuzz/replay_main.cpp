// Runs a fuzz target's entry point over files, without libFuzzer: how the seed corpus and
// every input a fuzzer ever found (fuzz/regressions/) are replayed in the normal test run.
// Usage: replay FILE_OR_DIRECTORY... ; exits non-zero when no file was given.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(std::uint8_t const* data, std::size_t size);

int main(int argc, char** argv)
{
    std::vector<std::filesystem::path> files;
    for (int k = 1; k < argc; ++k) {
        std::filesystem::path const given = argv[k];
        if (std::filesystem::is_directory(given)) {
            for (auto const& entry : std::filesystem::directory_iterator(given))
                if (entry.is_regular_file())
                    files.push_back(entry.path());
        } else {
            files.push_back(given);
        }
    }
    if (files.empty()) {
        std::cerr << "replay: no input files\n";
        return 2;
    }
    for (auto const& file : files) {
        std::ifstream in(file, std::ios::binary);
        if (!in) {
            std::cerr << "replay: cannot read " << file << '\n';
            return 2;
        }
        std::string const bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
        LLVMFuzzerTestOneInput(reinterpret_cast<std::uint8_t const*>(bytes.data()), bytes.size());
    }
    std::cout << "replay: " << files.size() << " inputs, no failure\n";
    return 0;
}
