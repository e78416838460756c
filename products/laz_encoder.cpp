#include "products/laz_encoder.h"

#include <cstring>
#include <map>
#include <memory>
#include <type_traits>

#include "core/error.h"
#include "products/little_endian.h"

namespace skyfall {
namespace {

// --- Entropy coding (LASzip's adaptation of FastAC) --------------------------

constexpr std::uint32_t kMinLength = 0x01000000u;  // renormalize below this interval length
constexpr std::uint32_t kMaxLength = 0xFFFFFFFFu;
constexpr std::uint32_t kBitLengthShift = 13;  // bit models: probability precision
constexpr std::uint32_t kBitMaxCount = 1u << kBitLengthShift;
constexpr std::uint32_t kSymbolLengthShift = 15;  // symbol models: distribution precision
constexpr std::uint32_t kSymbolMaxCount = 1u << kSymbolLengthShift;

// Adaptive binary model; probabilities are refreshed every few bits, more
// rarely as the model settles (the decoder repeats the same schedule).
struct BitModel {
  std::uint32_t update_cycle = 4, bits_until_update = 4;
  std::uint32_t bit_0_prob = 1u << (kBitLengthShift - 1), bit_0_count = 1, bit_count = 2;

  void Update() {
    if ((bit_count += update_cycle) > kBitMaxCount) {
      bit_count = (bit_count + 1) >> 1;
      bit_0_count = (bit_0_count + 1) >> 1;
      if (bit_0_count == bit_count) ++bit_count;
    }
    const std::uint32_t scale = 0x80000000u / bit_count;
    bit_0_prob = (bit_0_count * scale) >> (31 - kBitLengthShift);
    update_cycle = (5 * update_cycle) >> 2;
    if (update_cycle > 64) update_cycle = 64;
    bits_until_update = update_cycle;
  }
};

// Adaptive model over `symbols` symbols (2..2048), all equally likely at first.
struct SymbolModel {
  explicit SymbolModel(std::uint32_t symbols)
      : symbols(symbols), last_symbol(symbols - 1), distribution(symbols), symbol_count(symbols, 1) {
    update_cycle = symbols;
    Update();
    symbols_until_update = update_cycle = (symbols + 6) >> 1;
  }

  void Update() {
    if ((total_count += update_cycle) > kSymbolMaxCount) {
      total_count = 0;
      for (std::uint32_t n = 0; n < symbols; ++n) total_count += (symbol_count[n] = (symbol_count[n] + 1) >> 1);
    }
    const std::uint32_t scale = 0x80000000u / total_count;
    std::uint32_t sum = 0;
    for (std::uint32_t k = 0; k < symbols; ++k) {
      distribution[k] = (scale * sum) >> (31 - kSymbolLengthShift);
      sum += symbol_count[k];
    }
    update_cycle = (5 * update_cycle) >> 2;
    const std::uint32_t max_cycle = (symbols + 6) << 3;
    if (update_cycle > max_cycle) update_cycle = max_cycle;
    symbols_until_update = update_cycle;
  }

  std::uint32_t symbols, last_symbol;
  std::vector<std::uint32_t> distribution, symbol_count;
  std::uint32_t total_count = 0, update_cycle = 0, symbols_until_update = 0;
};

class ArithmeticEncoder {
 public:
  void EncodeBit(BitModel& m, std::uint32_t bit) {
    const std::uint32_t x = m.bit_0_prob * (length_ >> kBitLengthShift);
    if (bit == 0) {
      length_ = x;
      ++m.bit_0_count;
    } else {
      AddToBase(x);
      length_ -= x;
    }
    if (length_ < kMinLength) Renormalize();
    if (--m.bits_until_update == 0) m.Update();
  }

  void EncodeSymbol(SymbolModel& m, std::uint32_t sym) {
    if (sym == m.last_symbol) {
      const std::uint32_t x = m.distribution[sym] * (length_ >> kSymbolLengthShift);
      AddToBase(x);
      length_ -= x;
    } else {
      length_ >>= kSymbolLengthShift;
      const std::uint32_t x = m.distribution[sym] * length_;
      AddToBase(x);
      length_ = m.distribution[sym + 1] * length_ - x;
    }
    if (length_ < kMinLength) Renormalize();
    ++m.symbol_count[sym];
    if (--m.symbols_until_update == 0) m.Update();
  }

  // `bits` raw bits (1..32) of `sym`, equiprobable.
  void WriteBits(std::uint32_t bits, std::uint32_t sym) {
    if (bits > 19) {
      WriteBits(16, sym & 0xFFFFu);
      sym >>= 16;
      bits -= 16;
    }
    length_ >>= bits;
    AddToBase(sym * length_);
    if (length_ < kMinLength) Renormalize();
  }

  // Flushes the interval and appends the zero bytes the decoder's look-ahead
  // reads; returns the layer's bytes.
  std::string Finish() {
    const std::uint32_t init_base = base_;
    bool another_byte = true;
    if (length_ > 2 * kMinLength) {
      base_ += kMinLength;
      length_ = kMinLength >> 1;
    } else {
      base_ += kMinLength >> 1;
      length_ = kMinLength >> 9;
      another_byte = false;
    }
    if (init_base > base_) PropagateCarry();
    Renormalize();
    out_.append(another_byte ? 3 : 2, '\0');
    return std::move(out_);
  }

 private:
  void AddToBase(std::uint32_t x) {
    const std::uint32_t init_base = base_;
    base_ += x;
    if (init_base > base_) PropagateCarry();  // wrapped: carry into the bytes already out
  }
  void PropagateCarry() {
    for (std::size_t i = out_.size(); i-- > 0;) {
      auto& byte = reinterpret_cast<unsigned char&>(out_[i]);
      if (byte != 0xFF) {
        ++byte;
        return;
      }
      byte = 0;
    }
  }
  void Renormalize() {
    do {
      out_.push_back(static_cast<char>(base_ >> 24));
      base_ <<= 8;
    } while ((length_ <<= 8) < kMinLength);
  }

  std::uint32_t base_ = 0, length_ = kMaxLength;
  std::string out_;
};

// LASzip's integer compressor: a prediction's corrector is coded as the
// number k of its significant bits (one model per context), then its value
// within [-(2^k - 1), 2^k]: small k with one model per k, large k as the
// top `bits_high` bits modelled and the rest raw.
class IntegerCompressor {
 public:
  IntegerCompressor(std::uint32_t bits, std::uint32_t contexts, std::uint32_t bits_high = 8)
      : bits_high_(bits_high) {
    if (bits > 0 && bits < 32) {
      corr_bits_ = bits;
      corr_range_ = 1u << bits;
      corr_min_ = -static_cast<std::int64_t>(corr_range_ / 2);
      corr_max_ = corr_min_ + corr_range_ - 1;
    }
    for (std::uint32_t c = 0; c < contexts; ++c) k_models_.emplace_back(corr_bits_ + 1);
    for (std::uint32_t i = 1; i <= corr_bits_; ++i) {
      corrector_models_.emplace_back(i <= bits_high_ ? 1u << i : 1u << bits_high_);
    }
  }

  void Compress(ArithmeticEncoder& enc, std::int32_t pred, std::int32_t real, std::uint32_t context) {
    // Differences wrap in 32 bits, as LASzip's do.
    std::int64_t corr = static_cast<std::int32_t>(static_cast<std::uint32_t>(real) - static_cast<std::uint32_t>(pred));
    if (corr_range_ != 0) {
      if (corr < corr_min_) corr += corr_range_;
      else if (corr > corr_max_) corr -= corr_range_;
    }
    WriteCorrector(enc, corr, k_models_[context]);
  }

  std::uint32_t k() const { return k_; }

 private:
  void WriteCorrector(ArithmeticEncoder& enc, std::int64_t c, SymbolModel& k_model) {
    std::uint64_t c1 = c <= 0 ? static_cast<std::uint64_t>(-c) : static_cast<std::uint64_t>(c - 1);
    k_ = 0;
    while (c1) {
      c1 >>= 1;
      ++k_;
    }
    enc.EncodeSymbol(k_model, k_);
    if (k_ == 0) {  // c is 0 or 1
      enc.EncodeBit(corrector_bit_, static_cast<std::uint32_t>(c));
      return;
    }
    if (k_ >= 32) return;  // only c = corr_min lands here; its k says it all
    // Into [0, 2^k - 1]: the negative half below 2^(k-1), the positive above.
    const std::uint64_t v = c < 0 ? static_cast<std::uint64_t>(c + ((std::int64_t{1} << k_) - 1))
                                  : static_cast<std::uint64_t>(c - 1);
    SymbolModel& model = corrector_models_[k_ - 1];
    if (k_ <= bits_high_) {
      enc.EncodeSymbol(model, static_cast<std::uint32_t>(v));
    } else {
      const std::uint32_t low_bits = k_ - bits_high_;
      enc.EncodeSymbol(model, static_cast<std::uint32_t>(v >> low_bits));
      enc.WriteBits(low_bits, static_cast<std::uint32_t>(v & ((std::uint64_t{1} << low_bits) - 1)));
    }
  }

  std::uint32_t bits_high_;
  std::uint32_t corr_bits_ = 32, corr_range_ = 0;  // 32 bits: no folding
  std::int64_t corr_min_ = INT32_MIN, corr_max_ = INT32_MAX;
  std::vector<SymbolModel> k_models_;
  BitModel corrector_bit_;
  std::vector<SymbolModel> corrector_models_;  // for k = 1..corr_bits
  std::uint32_t k_ = 0;
};

// Running median of the last five values (LASzip's StreamingMedian5): the
// prediction of the next coordinate difference.
class Median5 {
 public:
  std::int32_t Get() const { return v_[2]; }
  void Add(std::int32_t x) {
    auto& v = v_;
    if (high_) {
      if (x < v[2]) {
        v[4] = v[3];
        v[3] = v[2];
        if (x < v[0]) {
          v[2] = v[1];
          v[1] = v[0];
          v[0] = x;
        } else if (x < v[1]) {
          v[2] = v[1];
          v[1] = x;
        } else {
          v[2] = x;
        }
      } else {
        if (x < v[3]) {
          v[4] = v[3];
          v[3] = x;
        } else {
          v[4] = x;
        }
        high_ = false;
      }
    } else {
      if (v[2] < x) {
        v[0] = v[1];
        v[1] = v[2];
        if (v[4] < x) {
          v[2] = v[3];
          v[3] = v[4];
          v[4] = x;
        } else if (v[3] < x) {
          v[2] = v[3];
          v[3] = x;
        } else {
          v[2] = x;
        }
      } else {
        if (v[1] < x) {
          v[0] = v[1];
          v[1] = x;
        } else {
          v[0] = x;
        }
        high_ = true;
      }
    }
  }

 private:
  std::array<std::int32_t, 5> v_{};
  bool high_ = true;
};

// --- POINT14 v3 for single returns on channel 0 -------------------------------
//
// With return 1 of 1 the return map, the return level and the previous
// return context are constants: m = 0, l = 0, cpr = 3 (single), lpr = 3
// (the last point was single, its GPS time unchanged). Every context
// below is LASzip's for those values.
constexpr std::uint32_t kDxContext = 1;  // LASzip's (n == 1) term of the X, Y and Z contexts

class Point14Layers {
 public:
  explicit Point14Layers(const LazRecord& first) : last_(first), last_z_(first.xyz[2]) {}

  void Add(const LazRecord& r) {
    // Layer 1: what changed (nothing among the constant fields; the model
    // is the one for lpr = 3), then X and Y.
    xy_.EncodeSymbol(changed_values_, 0);
    const std::int32_t dx = Diff(r.xyz[0], last_.xyz[0]);
    ic_dx_.Compress(xy_, median_dx_.Get(), dx, kDxContext);
    median_dx_.Add(dx);
    const std::uint32_t kx = ic_dx_.k();
    const std::int32_t dy = Diff(r.xyz[1], last_.xyz[1]);
    ic_dy_.Compress(xy_, median_dy_.Get(), dy, kDxContext + (kx < 20 ? (kx & ~1u) : 20));
    median_dy_.Add(dy);
    // Layer 2: Z predicted by the last Z.
    const std::uint32_t kxy = (ic_dx_.k() + ic_dy_.k()) / 2;
    ic_z_.Compress(z_, last_z_, r.xyz[2], kDxContext + (kxy < 18 ? (kxy & ~1u) : 18));
    last_z_ = r.xyz[2];
    // Layer 3: the class, in the context of the last class.
    const std::uint32_t ccc = ((last_.classification & 0x1Fu) << 1) + 1;  // + 1: the last point was single
    auto it = class_models_.try_emplace(ccc, 256).first;
    classification_.EncodeSymbol(it->second, r.classification);
    if (r.classification != last_.classification) class_changed_ = true;
    last_ = r;
  }

  // Appends the nine layer sizes, then returns the layers' bytes (the caller
  // writes them after every item's sizes).
  std::string Finish(std::string* sizes) {
    const std::string xy = xy_.Finish(), z = z_.Finish();
    const std::string cls = class_changed_ ? classification_.Finish() : std::string();
    PutLe(sizes, static_cast<std::uint32_t>(xy.size()));
    PutLe(sizes, static_cast<std::uint32_t>(z.size()));
    PutLe(sizes, static_cast<std::uint32_t>(cls.size()));
    // Flags, intensity, scan angle, user data, point source, GPS time: never
    // changed, so no bytes (the decoder then repeats the first point's).
    for (int layer = 0; layer < 6; ++layer) PutLe<std::uint32_t>(sizes, 0);
    return xy + z + cls;
  }

 private:
  static std::int32_t Diff(std::int32_t a, std::int32_t b) {
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) - static_cast<std::uint32_t>(b));
  }

  LazRecord last_;
  std::int32_t last_z_;
  ArithmeticEncoder xy_, z_, classification_;
  SymbolModel changed_values_{128};
  IntegerCompressor ic_dx_{32, 2}, ic_dy_{32, 22}, ic_z_{32, 20};
  Median5 median_dx_, median_dy_;
  std::map<std::uint32_t, SymbolModel> class_models_;  // created on first use, as LASzip's
  bool class_changed_ = false;
};

// --- RGB14 v3 -------------------------------------------------------------------

std::int32_t FoldU8(std::int32_t n) { return n < 0 ? n + 256 : (n > 255 ? n - 256 : n); }
std::int32_t ClampU8(std::int32_t n) { return n <= 0 ? 0 : (n >= 255 ? 255 : n); }

class Rgb14Layer {
 public:
  explicit Rgb14Layer(const LazRecord& first) : last_(first.rgb) {}

  // Which bytes changed, then each changed byte's difference; green and blue
  // are predicted from red's change when the colour is not grey.
  void Add(const LazRecord& r) {
    const auto& c = r.rgb;
    const auto lo = [](std::uint16_t v) { return static_cast<std::int32_t>(v & 0xFF); };
    const auto hi = [](std::uint16_t v) { return static_cast<std::int32_t>(v >> 8); };
    std::uint32_t sym = 0;
    for (int b = 0; b < 3; ++b) {
      sym |= std::uint32_t(lo(last_[b]) != lo(c[b])) << (2 * b);
      sym |= std::uint32_t(hi(last_[b]) != hi(c[b])) << (2 * b + 1);
    }
    const bool colour = lo(c[0]) != lo(c[1]) || lo(c[0]) != lo(c[2]) || hi(c[0]) != hi(c[1]) || hi(c[0]) != hi(c[2]);
    sym |= std::uint32_t(colour) << 6;
    enc_.EncodeSymbol(byte_used_, sym);
    std::int32_t diff_l = 0, diff_h = 0;
    if (sym & 1) {
      diff_l = lo(c[0]) - lo(last_[0]);
      enc_.EncodeSymbol(diff_[0], FoldU8(diff_l));
    }
    if (sym & 2) {
      diff_h = hi(c[0]) - hi(last_[0]);
      enc_.EncodeSymbol(diff_[1], FoldU8(diff_h));
    }
    if (sym & (1 << 6)) {
      if (sym & (1 << 2)) enc_.EncodeSymbol(diff_[2], FoldU8(lo(c[1]) - ClampU8(diff_l + lo(last_[1]))));
      if (sym & (1 << 4)) {
        diff_l = (diff_l + lo(c[1]) - lo(last_[1])) / 2;
        enc_.EncodeSymbol(diff_[4], FoldU8(lo(c[2]) - ClampU8(diff_l + lo(last_[2]))));
      }
      if (sym & (1 << 3)) enc_.EncodeSymbol(diff_[3], FoldU8(hi(c[1]) - ClampU8(diff_h + hi(last_[1]))));
      if (sym & (1 << 5)) {
        diff_h = (diff_h + hi(c[1]) - hi(last_[1])) / 2;
        enc_.EncodeSymbol(diff_[5], FoldU8(hi(c[2]) - ClampU8(diff_h + hi(last_[2]))));
      }
    }
    if (sym) changed_ = true;
    last_ = c;
  }

  std::string Finish(std::string* sizes) {
    std::string bytes = enc_.Finish();
    if (!changed_) bytes.clear();
    PutLe(sizes, static_cast<std::uint32_t>(bytes.size()));
    return bytes;
  }

 private:
  std::array<std::uint16_t, 3> last_;
  ArithmeticEncoder enc_;
  SymbolModel byte_used_{128};
  std::array<SymbolModel, 6> diff_{SymbolModel(256), SymbolModel(256), SymbolModel(256),
                                   SymbolModel(256), SymbolModel(256), SymbolModel(256)};
  bool changed_ = false;
};

// LASzip's item types and the versions written.
constexpr std::uint16_t kItemPoint14 = 10, kItemRgb14 = 11, kItemVersion = 3;
constexpr std::uint16_t kCompressorLayeredChunked = 3;

}  // namespace

std::string RawRecord7(const LazRecord& r) {
  std::string out;
  out.reserve(36);
  for (int a = 0; a < 3; ++a) PutLe(&out, static_cast<std::uint32_t>(r.xyz[a]));
  PutLe<std::uint16_t>(&out, 0);  // intensity: none from imagery
  out.push_back(0x11);            // return 1 of 1
  out.push_back(0);               // classification flags, scanner channel, scan direction, edge of flight line
  out.push_back(static_cast<char>(r.classification));
  out.push_back(0);                // user data
  PutLe<std::uint16_t>(&out, 0);   // scan angle
  PutLe<std::uint16_t>(&out, 0);   // point source ID
  PutLe<std::uint64_t>(&out, 0);   // GPS time 0.0
  for (int b = 0; b < 3; ++b) PutLe(&out, r.rgb[b]);
  return out;
}

std::string EncodeLazChunk(const std::vector<LazRecord>& records) {
  if (records.empty()) throw Error("laz", "chunk", "a LAZ chunk needs at least one point");
  std::string out = RawRecord7(records.front());
  Point14Layers point(records.front());
  Rgb14Layer rgb(records.front());
  for (std::size_t i = 1; i < records.size(); ++i) {
    point.Add(records[i]);
    rgb.Add(records[i]);
  }
  PutLe(&out, static_cast<std::uint32_t>(records.size()));
  const std::string point_bytes = point.Finish(&out);
  const std::string rgb_bytes = rgb.Finish(&out);
  out += point_bytes;
  out += rgb_bytes;
  return out;
}

std::string EncodeLazChunkTable(const std::vector<LazChunkEntry>& chunks, bool variable_size) {
  std::string out;
  PutLe<std::uint32_t>(&out, 0);  // table version
  PutLe(&out, static_cast<std::uint32_t>(chunks.size()));
  if (chunks.empty()) return out;
  ArithmeticEncoder enc;
  IntegerCompressor ic(32, 2);
  for (std::size_t i = 0; i < chunks.size(); ++i) {
    const LazChunkEntry prev = i ? chunks[i - 1] : LazChunkEntry{};
    if (variable_size) {
      ic.Compress(enc, static_cast<std::int32_t>(prev.points), static_cast<std::int32_t>(chunks[i].points), 0);
    }
    ic.Compress(enc, static_cast<std::int32_t>(prev.bytes), static_cast<std::int32_t>(chunks[i].bytes), 1);
  }
  return out + enc.Finish();
}

std::string LaszipVlrPayload(std::uint32_t chunk_points) {
  std::string out;
  PutLe(&out, kCompressorLayeredChunked);
  PutLe<std::uint16_t>(&out, 0);  // coder: arithmetic
  out.push_back(3);               // LASzip version the stream follows: 3.4 r3
  out.push_back(4);
  PutLe<std::uint16_t>(&out, 3);
  PutLe<std::uint32_t>(&out, 0);  // options
  PutLe(&out, chunk_points);
  PutLe(&out, ~std::uint64_t{0});  // special EVLRs: none (-1)
  PutLe(&out, ~std::uint64_t{0});  // their offset: none (-1)
  PutLe<std::uint16_t>(&out, 2);   // items
  for (const auto& [type, size] : {std::pair<std::uint16_t, std::uint16_t>{kItemPoint14, 30}, {kItemRgb14, 6}}) {
    PutLe(&out, type);
    PutLe(&out, size);
    PutLe(&out, kItemVersion);
  }
  return out;
}

}  // namespace skyfall
