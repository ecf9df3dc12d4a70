#pragma once

// A program run as a child process for end-to-end tests, its stdout and stderr written to
// one file that the test reads. A kugel-server child is found by the port it logs.

#include <chrono>
#include <csignal>
#include <cstdint>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <optional>
#include <spawn.h>
#include <sstream>
#include <stdexcept>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace kugel::test_support {

class child_process
{
public:
    using clock = std::chrono::steady_clock;

    /// Starts `program` with `args`; its stdout and stderr go to `output`.
    child_process(std::string const& program, std::vector<std::string> args,
                  std::filesystem::path output)
        : output_(std::move(output))
    {
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, 1, output_.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                         0644);
        posix_spawn_file_actions_adddup2(&actions, 1, 2);
        args.insert(args.begin(), program);
        std::vector<char*> argv;
        for (std::string& a : args)
            argv.push_back(a.data());
        argv.push_back(nullptr);
        int const spawned =
            posix_spawn(&pid_, program.c_str(), &actions, nullptr, argv.data(), environ);
        posix_spawn_file_actions_destroy(&actions);
        if (spawned != 0)
            throw std::runtime_error("cannot start " + program);
    }

    ~child_process()
    {
        if (!status_) {
            kill(pid_, SIGKILL);
            waitpid(pid_, nullptr, 0);
        }
    }

    child_process(child_process const&) = delete;
    child_process& operator=(child_process const&) = delete;

    /// Everything it wrote so far.
    std::string output() const
    {
        std::ifstream in(output_);
        std::stringstream text;
        text << in.rdbuf();
        return text.str();
    }

    /// Waits until its output holds `needle`; returns that line, or "" when it exited or
    /// `timeout` passed first.
    std::string wait_for_output(std::string const& needle, std::chrono::milliseconds timeout)
    {
        auto const deadline = clock::now() + timeout;
        for (;;) {
            std::string const text = output();
            if (auto const at = text.find(needle); at != std::string::npos) {
                auto const start = text.rfind('\n', at);
                auto const end = text.find('\n', at);
                return text.substr(start == std::string::npos ? 0 : start + 1,
                                   end == std::string::npos
                                       ? std::string::npos
                                       : end - (start == std::string::npos ? 0 : start + 1));
            }
            if (exited() || clock::now() > deadline)
                return "";
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
    }

    void signal(int number) { kill(pid_, number); }

    /// Its exit status once it ended (-1 when a signal ended it), or nullopt when it is still
    /// running after `timeout` (then it is left running).
    std::optional<int> wait(std::chrono::milliseconds timeout)
    {
        auto const deadline = clock::now() + timeout;
        while (!exited()) {
            if (clock::now() > deadline)
                return std::nullopt;
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        return WIFEXITED(*status_) ? WEXITSTATUS(*status_) : -1;
    }

private:
    bool exited()
    {
        if (status_)
            return true;
        int status = 0;
        if (waitpid(pid_, &status, WNOHANG) == pid_)
            status_ = status;
        return status_.has_value();
    }

    std::filesystem::path output_;
    pid_t pid_ = -1;
    std::optional<int> status_;
};

/// kugel-server on a free port of 127.0.0.1, with `args` (rooms, limits); stopped with
/// SIGTERM when it goes out of scope.
class server_child
{
public:
    server_child(std::string const& program, std::vector<std::string> args,
                 std::filesystem::path const& log)
        : process_(program, with_port_zero(std::move(args)), log)
    {
        std::string const line =
            process_.wait_for_output("serving on http://127.0.0.1:", std::chrono::seconds(30));
        if (line.empty())
            throw std::runtime_error("kugel-server did not start:\n" + process_.output());
        auto const at = line.find("127.0.0.1:") + 10;
        port_ = static_cast<std::uint16_t>(std::stoul(line.substr(at)));
    }

    ~server_child() { stop(); }

    std::uint16_t port() const { return port_; }
    std::string url(std::string const& room) const
    {
        return "ws://127.0.0.1:" + std::to_string(port_) + "/ws/" + room;
    }

    /// SIGTERM, and its exit status (nullopt when it did not end within 10 s).
    std::optional<int> stop()
    {
        if (!stopped_) {
            process_.signal(SIGTERM);
            stopped_ = process_.wait(std::chrono::seconds(10));
            if (!stopped_)
                stopped_ = std::optional<int>{}; // the destructor kills it
        }
        return *stopped_;
    }

    /// SIGKILL: no shutdown at all, as in a crash or an OOM kill.
    void kill()
    {
        process_.signal(SIGKILL);
        stopped_ = process_.wait(std::chrono::seconds(10));
    }

    std::string log() const { return process_.output(); }

private:
    static std::vector<std::string> with_port_zero(std::vector<std::string> args)
    {
        args.insert(args.begin(), {"--port", "0", "--threads", "2"});
        return args;
    }

    child_process process_;
    std::uint16_t port_ = 0;
    std::optional<std::optional<int>> stopped_;
};

} // namespace kugel::test_support
