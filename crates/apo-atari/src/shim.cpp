// A C ABI over the Arcade Learning Environment's ALEInterface, for apo-atari's Rust side.
// Every function catches C++ exceptions: errors come back as a null handle or a negative
// status, with the message readable through ale_last_error.
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "ale/ale_interface.hpp"
#include "ale/common/Log.hpp"

namespace {
thread_local std::string last_error;

int fail(const std::exception& e) {
  last_error = e.what();
  return -1;
}
}  // namespace

extern "C" {

const char* ale_last_error() { return last_error.c_str(); }

// The game of `rom` as the ALE names it from the file's MD5 (`pong`, `air_raid`), copied with
// its NUL into `out` (`cap` bytes); its length, or 0 when `rom` is not a ROM the ALE supports,
// -1 when the name does not fit. The ALE ends the process on a missing or unknown ROM, so
// callers check first.
int ale_rom_name(const char* rom, char* out, int cap) {
  try {
    auto name = ale::ALEInterface::isSupportedROM(rom);
    if (!name.has_value()) return 0;
    if (cap <= 0 || name->size() + 1 > static_cast<size_t>(cap)) return -1;
    std::memcpy(out, name->c_str(), name->size() + 1);
    return static_cast<int>(name->size());
  } catch (const std::exception& e) {
    fail(e);
    return 0;
  }
}

// A new emulator with `rom` loaded: the ALE seeded with `seed`, sticky actions repeating with
// probability `repeat_action_probability`, episodes cut after `max_frames` frames (0: never).
void* ale_new(const char* rom, int seed, float repeat_action_probability, int max_frames) {
  try {
    ale::Logger::setMode(ale::Logger::Error);
    auto* a = new ale::ALEInterface();
    try {
      a->setInt("random_seed", seed);
      a->setFloat("repeat_action_probability", repeat_action_probability);
      a->setInt("max_num_frames_per_episode", max_frames);
      a->loadROM(rom);
    } catch (...) {
      delete a;
      throw;
    }
    return a;
  } catch (const std::exception& e) {
    fail(e);
    return nullptr;
  }
}

void ale_delete(void* a) { delete static_cast<ale::ALEInterface*>(a); }

// Writes up to `capacity` of the minimal action set's action codes into `out`; returns the
// set's size.
int ale_minimal_actions(void* a, int* out, int capacity) {
  auto set = static_cast<ale::ALEInterface*>(a)->getMinimalActionSet();
  for (size_t i = 0; i < set.size() && static_cast<int>(i) < capacity; ++i) {
    out[i] = static_cast<int>(set[i]);
  }
  return static_cast<int>(set.size());
}

// One emulator frame with action code `action`; the frame's reward into `reward`.
int ale_act(void* a, int action, int* reward) {
  try {
    *reward = static_cast<ale::ALEInterface*>(a)->act(static_cast<ale::Action>(action));
    return 0;
  } catch (const std::exception& e) {
    return fail(e);
  }
}

// 1 when the game is over, else 0 (the frame limit is reported by ale_game_truncated).
int ale_game_over(void* a) {
  return static_cast<ale::ALEInterface*>(a)->game_over(false) ? 1 : 0;
}

// 1 when the episode was cut by the frame limit, else 0.
int ale_game_truncated(void* a) {
  return static_cast<ale::ALEInterface*>(a)->game_truncated() ? 1 : 0;
}

int ale_reset(void* a) {
  try {
    static_cast<ale::ALEInterface*>(a)->reset_game();
    return 0;
  } catch (const std::exception& e) {
    return fail(e);
  }
}

// Reseeds the ALE (and reloads the ROM, as a seeded reset does in ale-py).
int ale_reseed(void* a, const char* rom, int seed) {
  try {
    auto* i = static_cast<ale::ALEInterface*>(a);
    i->setInt("random_seed", seed);
    i->loadROM(rom);
    return 0;
  } catch (const std::exception& e) {
    return fail(e);
  }
}

// Copies the 128 RAM bytes into `out`.
void ale_ram(void* a, unsigned char* out) {
  const auto& ram = static_cast<ale::ALEInterface*>(a)->getRAM();
  std::memcpy(out, ram.array(), ram.size());
}

// The screen's width and height in pixels (160 × 210 on the Atari 2600).
void ale_screen_size(void* a, int* width, int* height) {
  const auto& screen = static_cast<ale::ALEInterface*>(a)->getScreen();
  *width = static_cast<int>(screen.width());
  *height = static_cast<int>(screen.height());
}

// Copies the screen as RGB bytes, rows from the top, into `out`, which holds
// 3 × width × height bytes (ale_screen_size).
int ale_screen_rgb(void* a, unsigned char* out) {
  try {
    thread_local std::vector<unsigned char> rgb;
    static_cast<ale::ALEInterface*>(a)->getScreenRGB(rgb);
    std::memcpy(out, rgb.data(), rgb.size());
    return 0;
  } catch (const std::exception& e) {
    return fail(e);
  }
}

int ale_lives(void* a) { return static_cast<ale::ALEInterface*>(a)->lives(); }

int ale_episode_frame(void* a) {
  return static_cast<ale::ALEInterface*>(a)->getEpisodeFrameNumber();
}
}
