#include "mcslam/perception/detector.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/dnn.hpp>
#include <opencv2/dnn/all_layers.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <variant>

#include "mcslam/core/error.hpp"

namespace mcslam::perception {
namespace {

// Ultralytics keeps at most this many boxes per image after NMS (its max_det default); a cap
// also bounds the cost of a degenerate output that passes the threshold everywhere.
constexpr std::size_t kMaxDetections = 300;
// YOLOX heads (P3, P4, P5).
constexpr int kYoloxStrides[] = {8, 16, 32};
constexpr double kPadGrey = 114.0;

// --- a minimal protobuf reader ------------------------------------------------------------------
//
// OpenCV parses the ONNX file but exposes neither ModelProto.metadata_props (where Ultralytics
// stores the class names) nor the graph's input shape. Both sit in a few small messages, so a
// reader of the wire format suffices: it walks one message's fields and skips the payload of
// every field it does not need (seeking over the weights instead of reading them). Every length
// is checked against the enclosing message, so garbage ends the walk instead of reading out of
// bounds or allocating without limit.

struct ProtoField {
  std::uint32_t number = 0;
  int wire_type = 0;
  std::uint64_t value = 0;   // wire type 0
  std::uint64_t offset = 0;  // wire type 2: payload position in the stream
  std::uint64_t length = 0;  // wire type 2: payload size
};

class ProtoReader {
 public:
  ProtoReader(std::istream& in, std::uint64_t begin, std::uint64_t end)
      : in_(in), pos_(begin), end_(end) {}

  /// The next field of the message, or false at its end or on malformed data.
  bool next(ProtoField& field) {
    if (pos_ >= end_ || !seek(pos_)) return false;
    std::uint64_t tag = 0;
    if (!read_varint(tag)) return false;
    field = ProtoField{};
    field.number = static_cast<std::uint32_t>(tag >> 3);
    field.wire_type = static_cast<int>(tag & 7u);
    if (field.number == 0 || (tag >> 3) > 0x1fffffffu) return false;
    switch (field.wire_type) {
      case 0:
        return read_varint(field.value);
      case 1:
        return advance(8);
      case 5:
        return advance(4);
      case 2:
        if (!read_varint(field.length) || field.length > end_ - pos_) return false;
        field.offset = pos_;
        pos_ += field.length;
        return true;
      default:  // groups (3, 4) are obsolete and absent from ONNX; 6, 7 are invalid
        return false;
    }
  }

  /// A nested message's reader.
  ProtoReader nested(const ProtoField& field) const {
    return ProtoReader(in_, field.offset, field.offset + field.length);
  }

  /// A length-delimited field's bytes, or nullopt when longer than `limit` or unreadable.
  std::optional<std::string> bytes(const ProtoField& field, std::uint64_t limit) {
    if (field.wire_type != 2 || field.length > limit || !seek(field.offset)) return std::nullopt;
    std::string out(static_cast<std::size_t>(field.length), '\0');
    if (!in_.read(out.data(), static_cast<std::streamsize>(out.size()))) {
      in_.clear();
      return std::nullopt;
    }
    return out;
  }

 private:
  bool seek(std::uint64_t pos) {
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(pos));
    return static_cast<bool>(in_);
  }
  bool advance(std::uint64_t n) {
    if (n > end_ - pos_) return false;
    pos_ += n;
    return true;
  }
  bool read_varint(std::uint64_t& value) {
    value = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (pos_ >= end_) return false;
      const int c = in_.get();
      if (c == std::char_traits<char>::eof()) {
        in_.clear();
        return false;
      }
      ++pos_;
      value |= static_cast<std::uint64_t>(c & 0x7f) << shift;
      if ((c & 0x80) == 0) return true;
    }
    return false;  // more than 10 bytes
  }

  std::istream& in_;
  std::uint64_t pos_;
  std::uint64_t end_;
};

// Metadata values and names are small; a limit keeps a corrupt length from allocating gigabytes.
constexpr std::uint64_t kMaxStringBytes = 16u << 20;

// StringStringEntryProto {key = 1, value = 2}.
std::optional<std::pair<std::string, std::string>> read_entry(ProtoReader reader) {
  std::pair<std::string, std::string> entry;
  ProtoField f;
  while (reader.next(f)) {
    if (f.wire_type != 2 || (f.number != 1 && f.number != 2)) continue;
    auto text = reader.bytes(f, kMaxStringBytes);
    if (!text) return std::nullopt;
    (f.number == 1 ? entry.first : entry.second) = std::move(*text);
  }
  if (entry.first.empty()) return std::nullopt;
  return entry;
}

// ValueInfoProto {type = 2: TypeProto {tensor_type = 1: Tensor {shape = 2: TensorShapeProto
// {dim = 1: Dimension {dim_value = 1, dim_param = 2}}}}}.
std::vector<std::int64_t> read_input_shape(ProtoReader value_info) {
  const auto child = [](ProtoReader reader, std::uint32_t number) -> std::optional<ProtoReader> {
    ProtoField f;
    while (reader.next(f))
      if (f.number == number && f.wire_type == 2) return reader.nested(f);
    return std::nullopt;
  };
  auto type = child(value_info, 2);
  if (!type) return {};
  auto tensor = child(*type, 1);
  if (!tensor) return {};
  auto shape = child(*tensor, 2);
  if (!shape) return {};
  std::vector<std::int64_t> dims;
  ProtoField f;
  while (shape->next(f)) {
    if (f.number != 1 || f.wire_type != 2) continue;
    ProtoReader dim = shape->nested(f);
    std::int64_t value = -1;  // dim_param (symbolic) or absent: unknown
    ProtoField d;
    while (dim.next(d))
      if (d.number == 1 && d.wire_type == 0) value = static_cast<std::int64_t>(d.value);
    dims.push_back(value);
    if (dims.size() > 16) return {};
  }
  return dims;
}

// --- class names --------------------------------------------------------------------------------

class ReprParser {
 public:
  explicit ReprParser(const std::string& text) : s_(text) {}

  void skip_space() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  bool consume(char c) {
    skip_space();
    if (i_ < s_.size() && s_[i_] == c) {
      ++i_;
      return true;
    }
    return false;
  }
  bool at_end() {
    skip_space();
    return i_ == s_.size();
  }
  std::optional<long> integer() {
    skip_space();
    const std::size_t start = i_;
    while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_])) && i_ - start < 9)
      ++i_;
    if (i_ == start) return std::nullopt;
    return std::stol(s_.substr(start, i_ - start));
  }
  // A Python str repr: 'text' or "text" with backslash escapes.
  std::optional<std::string> quoted() {
    skip_space();
    if (i_ >= s_.size() || (s_[i_] != '\'' && s_[i_] != '"')) return std::nullopt;
    const char quote = s_[i_++];
    std::string out;
    while (i_ < s_.size()) {
      const char c = s_[i_++];
      if (c == quote) return out;
      if (c == '\\' && i_ < s_.size()) {
        const char e = s_[i_++];
        out += e == 'n' ? '\n' : e == 't' ? '\t' : e;
      } else {
        out += c;
      }
    }
    return std::nullopt;
  }

 private:
  const std::string& s_;
  std::size_t i_ = 0;
};

// --- network surgery for OpenCV 4.6 -------------------------------------------------------------

std::int64_t shape_total(const cv::dnn::MatShape& shape, int begin, int end) {
  std::int64_t t = 1;
  for (int i = begin; i < end; ++i) t *= shape[static_cast<std::size_t>(i)];
  return t;
}

// Ultralytics' head ends with dbox = dist2bbox(...) * strides: a Mul of the 1x4xN box tensor by
// the 1xN stride constant (/model.22/Mul_2 in YOLOv8n, /model.23/... in YOLO11). OpenCV 4.6
// imports a Mul by a non-scalar constant as a Scale layer, which multiplies a run of axes that
// starts at its `axis` (1, the channel axis) by the constant, and it never finds a run of 4xN
// elements equal to N: forward() asserts. ONNX broadcasting aligns the constant with the
// *trailing* axes instead, so for such a layer the right run starts where the trailing axes'
// product equals the constant's size: setting ScaleLayer::axis (a public member) there gives
// exactly the ONNX result. Only layers whose forward() would otherwise fail are touched, and
// only when the constant's last dimension matches the input's last dimension (right
// alignment), so the fix is the ONNX semantics and nothing else. Works for any N (2100 at 320,
// 8400 at 640) and any head index. Returns the number of layers adjusted.
int fix_trailing_broadcast_scales(cv::dnn::Net& net, const cv::dnn::MatShape& input_shape) {
  std::vector<int> ids;
  std::vector<std::vector<cv::dnn::MatShape>> in_shapes, out_shapes;
  net.getLayersShapes(input_shape, ids, in_shapes, out_shapes);
  int adjusted = 0;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    cv::Ptr<cv::dnn::Layer> layer = net.getLayer(ids[i]);
    if (!layer || layer->type != "Scale" || in_shapes[i].size() != 1 || layer->blobs.size() != 1)
      continue;
    cv::Ptr<cv::dnn::ScaleLayer> scale = layer.dynamicCast<cv::dnn::ScaleLayer>();
    if (!scale || scale->hasBias) continue;
    const cv::dnn::MatShape& in = in_shapes[i][0];
    const cv::Mat& weights = layer->blobs[0];
    const auto count = static_cast<std::int64_t>(weights.total());
    const int dims = static_cast<int>(in.size());
    if (count <= 1 || dims < 2 || scale->axis < 0 || scale->axis >= dims) continue;
    // The search OpenCV's Scale::forward does: some run of axes from `axis` on must hold
    // exactly `count` elements.
    bool works = false;
    for (int end = scale->axis + 1; end <= dims && !works; ++end)
      works = shape_total(in, scale->axis, end) == count;
    if (works) continue;
    if (weights.dims < 1 || weights.size[weights.dims - 1] != in.back()) continue;
    for (int axis = dims - 1; axis >= 1; --axis) {
      if (shape_total(in, axis, dims) == count) {
        scale->axis = axis;
        ++adjusted;
        break;
      }
    }
  }
  return adjusted;
}

std::string describe_shape(const cv::Mat& m) {
  std::string s;
  for (int i = 0; i < m.dims; ++i) s += (i ? "x" : "") + std::to_string(m.size[i]);
  return s.empty() ? "empty" : s;
}

std::string opencv_message(const cv::Exception& e) {
  std::string msg = e.err.empty() ? std::string(e.what()) : e.err;
  if (!e.func.empty()) msg += " in " + e.func;
  return msg;
}

// The anchors of a three-level head (strides 8, 16, 32: YOLOX, YOLOv8, YOLO11) for an input.
int yolox_anchor_count(cv::Size input) {
  int n = 0;
  for (int s : kYoloxStrides) n += (input.width / s) * (input.height / s);
  return n;
}

// --- running a YOLOv8 graph at another input size ---------------------------------------------
//
// The convolutions take any input size, but the stock Ultralytics export computes its anchor
// grid at export time: the DFL's reshapes hold the anchor count N, two constants hold the
// anchor centres (1x2xN: x + 0.5 and y + 0.5 in grid cells, level after level) and the stride
// multiplication holds the stride of each anchor (1xN). For another input these are exactly the
// same constructions with another N, so they are rebuilt here; a constant of N values that is
// not what the export computes (checked value by value) stops the change with an error.

// The head constant of `rows` rows (1: strides, 2: anchor centres) for an input, as the export
// lays it out.
std::vector<float> head_constant(int rows, cv::Size input) {
  std::vector<float> x, y, stride;
  for (int s : kYoloxStrides) {
    for (int gy = 0; gy < input.height / s; ++gy) {
      for (int gx = 0; gx < input.width / s; ++gx) {
        x.push_back(static_cast<float>(gx) + 0.5f);
        y.push_back(static_cast<float>(gy) + 0.5f);
        stride.push_back(static_cast<float>(s));
      }
    }
  }
  if (rows == 1) return stride;
  x.insert(x.end(), y.begin(), y.end());
  return x;
}

// Rebuilds one layer constant of the last dimension `from`'s anchor count for `to`; false when
// it is not an anchor constant of the export.
bool regrid_constant(cv::Mat& blob, cv::Size from, cv::Size to) {
  const int n_old = yolox_anchor_count(from);
  if (blob.type() != CV_32F || !blob.isContinuous() || blob.total() % n_old != 0) return false;
  const int rows = static_cast<int>(blob.total() / n_old);
  if (rows != 1 && rows != 2) return false;
  const std::vector<float> expected = head_constant(rows, from);
  const float* values = blob.ptr<float>();
  for (std::size_t i = 0; i < expected.size(); ++i)
    if (std::abs(values[i] - expected[i]) > 1e-4f) return false;
  std::vector<int> dims(blob.size.p, blob.size.p + blob.dims);
  dims.back() = yolox_anchor_count(to);
  const std::vector<float> rebuilt = head_constant(rows, to);
  cv::Mat out(blob.dims, dims.data(), CV_32F);
  std::copy(rebuilt.begin(), rebuilt.end(), out.ptr<float>());
  blob = out;
  return true;
}

// Re-grids every layer that holds the anchor count of `from`. Returns the number of layers
// changed, or the problem.
std::variant<int, std::string> regrid_head(cv::dnn::Net& net, cv::Size from, cv::Size to) {
  const int n_old = yolox_anchor_count(from);
  const int n_new = yolox_anchor_count(to);
  int changed = 0;
  for (const cv::String& name : net.getLayerNames()) {
    cv::Ptr<cv::dnn::Layer> layer = net.getLayer(net.getLayerId(name));
    if (!layer) continue;
    bool touched = false;
    if (cv::Ptr<cv::dnn::ReshapeLayer> reshape = layer.dynamicCast<cv::dnn::ReshapeLayer>()) {
      for (int& d : reshape->newShapeDesc) {
        if (d != n_old) continue;
        d = n_new;
        touched = true;
      }
    }
    for (cv::Mat& blob : layer->blobs) {
      if (blob.dims < 1 || blob.size[blob.dims - 1] != n_old) continue;
      if (!regrid_constant(blob, from, to))
        return "layer " + name + " holds a constant of " + std::to_string(n_old) +
               " values that is not the export's anchor grid";
      touched = true;
    }
    changed += touched ? 1 : 0;
  }
  return changed;
}

// --- decoding -----------------------------------------------------------------------------------

struct Candidate {
  cv::Rect2d box;  // image pixels, not yet clipped
  float score;
  int index;  // class index in the model's output
};

// Class-wise NMS (OpenCV 4.6 has no NMSBoxesBatched): one NMSBoxes call per class present, then
// all kept boxes by decreasing score, clipped to the image (empty ones dropped).
std::vector<Detection> suppress(const std::vector<Candidate>& candidates,
                                const std::vector<std::string>& names,
                                const DetectorOptions& options, cv::Size image_size) {
  if (candidates.empty()) return {};
  std::map<int, std::vector<std::size_t>> by_class;
  for (std::size_t i = 0; i < candidates.size(); ++i) by_class[candidates[i].index].push_back(i);
  std::vector<std::size_t> keep;
  std::vector<cv::Rect2d> boxes;
  std::vector<float> scores;
  std::vector<int> kept;
  for (const auto& [index, members] : by_class) {
    boxes.clear();
    scores.clear();
    for (std::size_t i : members) {
      boxes.push_back(candidates[i].box);
      scores.push_back(candidates[i].score);
    }
    cv::dnn::NMSBoxes(boxes, scores, static_cast<float>(options.confidence),
                      static_cast<float>(options.nms_iou), kept);
    for (int k : kept) keep.push_back(members[static_cast<std::size_t>(k)]);
  }
  std::stable_sort(keep.begin(), keep.end(), [&](std::size_t a, std::size_t b) {
    return candidates[a].score > candidates[b].score;
  });

  const cv::Rect2d bounds(0.0, 0.0, image_size.width, image_size.height);
  std::vector<Detection> out;
  out.reserve(std::min(keep.size(), kMaxDetections));
  for (std::size_t k : keep) {
    const Candidate& c = candidates[k];
    const cv::Rect2d clipped = c.box & bounds;
    if (clipped.width <= 0.0 || clipped.height <= 0.0) continue;
    Detection d;
    d.box = cv::Rect2f(clipped);
    d.class_name = static_cast<std::size_t>(c.index) < names.size()
                       ? names[static_cast<std::size_t>(c.index)]
                       : "class" + std::to_string(c.index);
    d.class_id = coco_class_id(d.class_name);
    d.score = c.score;
    out.push_back(std::move(d));
    if (out.size() == kMaxDetections) break;
  }
  return out;
}

// A 2-D CV_32F header over a 1xAxB (or AxB) tensor; empty when it is neither.
cv::Mat as_2d(const cv::Mat& m) {
  if (m.empty() || m.type() != CV_32F) return {};
  if (m.dims == 2) return m.isContinuous() ? m : m.clone();
  if (m.dims == 3 && m.size[0] == 1 && m.isContinuous())
    return cv::Mat(m.size[1], m.size[2], CV_32F, const_cast<uchar*>(m.data));
  return {};
}

cv::Rect2d to_image_box(double cx, double cy, double w, double h, const Letterbox& lb) {
  const cv::Point2d a = lb.to_image({cx - 0.5 * w, cy - 0.5 * h});
  const cv::Point2d b = lb.to_image({cx + 0.5 * w, cy + 0.5 * h});
  return {a.x, a.y, b.x - a.x, b.y - a.y};
}

// Where the scaled image lands in the network input.
struct Placement {
  Letterbox letterbox;
  cv::Rect roi;
};

Placement place(cv::Size image, cv::Size input, DetectorFormat format) {
  Placement p;
  if (image.width <= 0 || image.height <= 0 || input.width <= 0 || input.height <= 0) return p;
  const double r = std::min(static_cast<double>(input.width) / image.width,
                            static_cast<double>(input.height) / image.height);
  if (format == DetectorFormat::kYoloV8) {
    // Ultralytics' LetterBox: round the scaled size, centre it, split odd padding as
    // round(d - 0.1) before and the rest after.
    const int w = std::clamp(static_cast<int>(std::lround(image.width * r)), 1, input.width);
    const int h = std::clamp(static_cast<int>(std::lround(image.height * r)), 1, input.height);
    const int left = static_cast<int>(std::lround((input.width - w) / 2.0 - 0.1));
    const int top = static_cast<int>(std::lround((input.height - h) / 2.0 - 0.1));
    p.roi = cv::Rect(std::max(left, 0), std::max(top, 0), w, h);
  } else {
    // YOLOX's preproc: truncate the scaled size, place it at the top-left corner.
    const int w = std::clamp(static_cast<int>(image.width * r), 1, input.width);
    const int h = std::clamp(static_cast<int>(image.height * r), 1, input.height);
    p.roi = cv::Rect(0, 0, w, h);
  }
  p.letterbox.scale = r;
  p.letterbox.offset = cv::Point2d(p.roi.x, p.roi.y);
  return p;
}

}  // namespace

// --- options, names -----------------------------------------------------------------------------

std::optional<std::string> DetectorOptions::check() const {
  const auto show = [](double v) {
    std::ostringstream s;
    s << v;
    return s.str();
  };
  if (!(confidence > 0.0 && confidence < 1.0))
    return "detector.confidence must be in (0, 1), got " + show(confidence);
  if (!(nms_iou > 0.0 && nms_iou <= 1.0))
    return "detector.nms_iou must be in (0, 1], got " + show(nms_iou);
  const bool own_size = input_size.width == 0 && input_size.height == 0;
  const auto stride_multiple = [](int v) { return v >= 32 && v <= 4096 && v % 32 == 0; };
  if (!own_size && !(stride_multiple(input_size.width) && stride_multiple(input_size.height)))
    return "the detector's input size must be 0x0 (the model's own) or multiples of 32 from 32 "
           "to 4096, got " +
           std::to_string(input_size.width) + "x" + std::to_string(input_size.height);
  return std::nullopt;
}

cv::Size input_size_for(cv::Size image, double scale) {
  if (!(scale > 0.0) || image.width <= 0 || image.height <= 0) return {};
  const auto side = [scale](int pixels) {
    const int n = static_cast<int>(std::ceil(pixels * scale / 32.0 - 1e-9));
    return std::clamp(n, 1, 4096 / 32) * 32;
  };
  return {side(image.width), side(image.height)};
}

const char* to_string(DetectorFormat format) {
  switch (format) {
    case DetectorFormat::kYoloV8:
      return "yolov8";
    case DetectorFormat::kYoloX:
      return "yolox";
  }
  return "unknown";
}

std::optional<std::string> OnnxModelInfo::find(const std::string& key) const {
  for (const auto& [k, v] : metadata)
    if (k == key) return v;
  return std::nullopt;
}

OnnxModelInfo read_onnx_info(const std::string& path) {
  OnnxModelInfo info;
  std::ifstream in(path, std::ios::binary);
  if (!in) return info;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size <= 0) return info;
  // ModelProto: graph = 7 (GraphProto: input = 11), metadata_props = 14.
  ProtoReader model(in, 0, static_cast<std::uint64_t>(size));
  ProtoField f;
  while (model.next(f)) {
    if (f.wire_type != 2) continue;
    if (f.number == 14) {
      if (auto entry = read_entry(model.nested(f))) info.metadata.push_back(std::move(*entry));
    } else if (f.number == 7 && info.input_shape.empty()) {
      ProtoReader graph = model.nested(f);
      ProtoField g;
      while (graph.next(g)) {
        if (g.number == 11 && g.wire_type == 2) {
          info.input_shape = read_input_shape(graph.nested(g));
          break;  // the image input is the first one
        }
      }
    }
  }
  return info;
}

std::optional<std::vector<std::string>> parse_class_names(const std::string& text) {
  ReprParser p(text);
  std::vector<std::string> names;
  if (p.consume('[')) {
    for (;;) {
      if (p.consume(']')) break;  // the end, after a trailing comma or of an empty list
      auto name = p.quoted();
      if (!name) return std::nullopt;
      names.push_back(std::move(*name));
      if (p.consume(',')) continue;
      if (p.consume(']')) break;
      return std::nullopt;
    }
    if (!p.at_end() || names.empty()) return std::nullopt;
    return names;
  }
  if (!p.consume('{')) return std::nullopt;
  std::map<long, std::string> by_index;
  for (;;) {
    if (p.consume('}')) break;
    const auto index = p.integer();
    if (!index || !p.consume(':')) return std::nullopt;
    auto name = p.quoted();
    if (!name || !by_index.emplace(*index, std::move(*name)).second) return std::nullopt;
    if (p.consume(',')) continue;
    if (p.consume('}')) break;
    return std::nullopt;
  }
  if (!p.at_end() || by_index.empty()) return std::nullopt;
  long expected = 0;
  for (auto& [index, name] : by_index) {
    if (index != expected++) return std::nullopt;
    names.push_back(std::move(name));
  }
  return names;
}

Letterbox make_letterbox(cv::Size image_size, cv::Size input_size, DetectorFormat format) {
  return place(image_size, input_size, format).letterbox;
}

// --- decoding -----------------------------------------------------------------------------------

std::vector<Detection> decode_yolov8(const cv::Mat& output_4c_by_n, const Letterbox& letterbox,
                                     const std::vector<std::string>& names,
                                     const DetectorOptions& options, cv::Size image_size) {
  const cv::Mat out = as_2d(output_4c_by_n);
  if (out.empty() || out.rows < 5 || letterbox.scale <= 0.0) return {};
  const int classes = out.rows - 4;
  const int n = out.cols;
  // Best class per anchor, row by row: the tensor is class-major, so this reads memory in order.
  std::vector<float> best(static_cast<std::size_t>(n), -1.0f);
  std::vector<int> best_class(static_cast<std::size_t>(n), 0);
  for (int c = 0; c < classes; ++c) {
    const float* row = out.ptr<float>(4 + c);
    for (int i = 0; i < n; ++i) {
      if (row[i] > best[static_cast<std::size_t>(i)]) {
        best[static_cast<std::size_t>(i)] = row[i];
        best_class[static_cast<std::size_t>(i)] = c;
      }
    }
  }
  const float* cx = out.ptr<float>(0);
  const float* cy = out.ptr<float>(1);
  const float* w = out.ptr<float>(2);
  const float* h = out.ptr<float>(3);
  const auto threshold = static_cast<float>(options.confidence);
  std::vector<Candidate> candidates;
  for (int i = 0; i < n; ++i) {
    const float score = best[static_cast<std::size_t>(i)];
    if (!(score >= threshold) || score > 1.0f) continue;
    if (!std::isfinite(cx[i]) || !std::isfinite(cy[i]) || !std::isfinite(w[i]) ||
        !std::isfinite(h[i]) || w[i] <= 0.0f || h[i] <= 0.0f)
      continue;
    candidates.push_back({to_image_box(cx[i], cy[i], w[i], h[i], letterbox), score,
                          best_class[static_cast<std::size_t>(i)]});
  }
  return suppress(candidates, names, options, image_size);
}

std::vector<Detection> decode_yolox(const cv::Mat& output_n_by_5c, cv::Size input_size,
                                    const Letterbox& letterbox,
                                    const std::vector<std::string>& names,
                                    const DetectorOptions& options, cv::Size image_size) {
  const cv::Mat out = as_2d(output_n_by_5c);
  if (out.empty() || out.cols < 6 || letterbox.scale <= 0.0 ||
      out.rows != yolox_anchor_count(input_size))
    return {};
  const int classes = out.cols - 5;
  const auto threshold = static_cast<float>(options.confidence);
  std::vector<Candidate> candidates;
  int row = 0;
  for (int stride : kYoloxStrides) {
    const int gw = input_size.width / stride;
    const int gh = input_size.height / stride;
    for (int gy = 0; gy < gh; ++gy) {
      for (int gx = 0; gx < gw; ++gx, ++row) {
        const float* r = out.ptr<float>(row);
        const float objectness = r[4];
        // score = objectness * class score <= objectness: most anchors stop here.
        if (!(objectness >= threshold)) continue;
        int best_class = 0;
        for (int c = 1; c < classes; ++c)
          if (r[5 + c] > r[5 + best_class]) best_class = c;
        const float score = objectness * r[5 + best_class];
        if (!(score >= threshold) || score > 1.0f) continue;
        // Raw offsets from the grid cell; exp() of a corrupt value is capped to stay finite.
        const double x = (r[0] + gx) * stride;
        const double y = (r[1] + gy) * stride;
        const double w = std::exp(std::min(static_cast<double>(r[2]), 20.0)) * stride;
        const double h = std::exp(std::min(static_cast<double>(r[3]), 20.0)) * stride;
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(w) || !std::isfinite(h))
          continue;
        candidates.push_back({to_image_box(x, y, w, h, letterbox), score, best_class});
      }
    }
  }
  return suppress(candidates, names, options, image_size);
}

// --- the detector -------------------------------------------------------------------------------

struct Detector::Impl {
  std::string path;
  DetectorOptions options;
  cv::dnn::Net net;
  DetectorFormat format = DetectorFormat::kYoloV8;
  cv::Size input_size;
  cv::Size graph_input_size;
  std::vector<std::string> names;
  std::vector<cv::String> output_names;
  int adjusted = 0;

  // Buffers reused by every detect() call: the padded 8-bit input and the network blob.
  cv::Mat padded;
  cv::Mat padded_float;
  cv::Mat blob;
  std::vector<cv::Mat> planes;  // headers into `blob`, in the order the split writes them
  std::vector<cv::Mat> outputs;

  void allocate() {
    padded.create(input_size, CV_8UC3);
    padded_float.create(input_size, CV_32FC3);
    const int dims[] = {1, 3, input_size.height, input_size.width};
    blob.create(4, dims, CV_32F);
    planes.clear();
    const std::size_t plane = static_cast<std::size_t>(input_size.area());
    for (int c = 0; c < 3; ++c)
      planes.emplace_back(input_size, CV_32F, blob.ptr<float>() + c * plane);
    // YOLOv8 wants RGB: the image's B, G, R channels go to planes 2, 1, 0.
    if (format == DetectorFormat::kYoloV8) std::swap(planes[0], planes[2]);
  }

  // Letterboxes `bgr` into `blob` (no allocation once the buffers exist).
  Letterbox preprocess(const cv::Mat& bgr) {
    const Placement p = place(bgr.size(), input_size, format);
    padded.setTo(cv::Scalar::all(kPadGrey));
    cv::Mat target = padded(p.roi);
    if (bgr.size() == p.roi.size())
      bgr.copyTo(target);
    else
      cv::resize(bgr, target, p.roi.size(), 0.0, 0.0, cv::INTER_LINEAR);
    const double scale = format == DetectorFormat::kYoloV8 ? 1.0 / 255.0 : 1.0;
    padded.convertTo(padded_float, CV_32F, scale);
    cv::split(padded_float, planes);
    return p.letterbox;
  }

  void forward(const cv::Mat& input) {
    net.setInput(input);
    net.forward(outputs, output_names);
  }

  std::vector<Detection> decode(const Letterbox& lb, cv::Size image_size) const {
    if (outputs.empty()) return {};
    return format == DetectorFormat::kYoloV8
               ? decode_yolov8(outputs[0], lb, names, options, image_size)
               : decode_yolox(outputs[0], input_size, lb, names, options, image_size);
  }

  // Loading, in the order the constructor runs them (each throws InputError naming the model).

  /// Reads the network from the ONNX file at `path`, for OpenCV's own backend on the CPU.
  void load_network();
  /// The input size: the graph's, else Ultralytics' imgsz metadata; then options.input_size when
  /// set, the network's head regridded for it.
  void settle_input_size(const OnnxModelInfo& info);
  /// Runs the graph once: proves OpenCV can run it and gives the output's shape.
  cv::Mat test_forward();
  /// The format from the output's shape; returns the number of classes.
  int settle_format(const cv::Mat& output, const OnnxModelInfo& info);
  /// The class names: the model's when they match the class count, else COCO's when the count
  /// is COCO's, else class0, class1, ...
  void settle_names(const OnnxModelInfo& info, int classes);
};

namespace {

/// Throws when the model file is missing, not a regular file or empty.
void check_model_file(const std::string& model_path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(model_path, ec)) throw InputError(file_error(model_path, "model file not found"));
  if (!fs::is_regular_file(model_path, ec))
    throw InputError(file_error(model_path, "the model is not a regular file"));
  if (fs::file_size(model_path, ec) == 0 && !ec)
    throw InputError(file_error(model_path, "the model file is empty"));
}

/// The input size of the graph's input shape, else of Ultralytics' imgsz metadata ("[320, 320]");
/// an empty size when neither gives one.
cv::Size declared_input_size(const OnnxModelInfo& info, const std::string& model_path) {
  const auto& shape = info.input_shape;
  if (shape.size() == 4 && shape[2] > 0 && shape[3] > 0 && shape[2] <= 8192 && shape[3] <= 8192) {
    if (shape[1] != 3 && shape[1] > 0)
      throw InputError(file_error(model_path, "the input has " + std::to_string(shape[1]) +
                                                  " channels; a 3-channel image input is needed"));
    return cv::Size(static_cast<int>(shape[3]), static_cast<int>(shape[2]));
  }
  if (const auto imgsz = info.find("imgsz")) {
    ReprParser p(*imgsz);
    std::optional<long> h, w;
    if (p.consume('[')) {
      h = p.integer();
      w = p.consume(',') ? p.integer() : h;
    }
    if (h && w && *h > 0 && *w > 0 && *h <= 8192 && *w <= 8192)
      return cv::Size(static_cast<int>(*w), static_cast<int>(*h));
  }
  return cv::Size();
}

}  // namespace

void Detector::Impl::load_network() {
  try {
    net = cv::dnn::readNetFromONNX(path);
  } catch (const cv::Exception& e) {
    throw InputError(
        file_error(path, "not an ONNX model OpenCV can read (" + opencv_message(e) + ")"));
  }
  if (net.empty()) throw InputError(file_error(path, "OpenCV loaded an empty network"));
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
}

void Detector::Impl::settle_input_size(const OnnxModelInfo& info) {
  input_size = declared_input_size(info, path);
  if (input_size.area() <= 0)
    throw InputError(file_error(path,
                                "the input size is not fixed in the graph (a 1x3xHxW input with "
                                "numbers for H and W is needed; export with a fixed image size)"));
  graph_input_size = input_size;
  if (options.input_size.area() > 0 && options.input_size != input_size) {
    std::variant<int, std::string> regridded;
    try {
      regridded = regrid_head(net, input_size, options.input_size);
    } catch (const cv::Exception& e) {
      regridded = opencv_message(e);
    }
    if (const auto* problem = std::get_if<std::string>(&regridded))
      throw InputError(
          file_error(path, "cannot run at " + std::to_string(options.input_size.width) + "x" +
                               std::to_string(options.input_size.height) + " (" + *problem + ")"));
    input_size = options.input_size;
  }
}

cv::Mat Detector::Impl::test_forward() {
  // The input values do not matter for the shape.
  try {
    const int dims[] = {1, 3, input_size.height, input_size.width};
    forward(cv::Mat(4, dims, CV_32F, cv::Scalar(kPadGrey / 255.0)));
    return outputs.at(0);
  } catch (const cv::Exception& e) {
    throw InputError(file_error(
        path, "OpenCV " CV_VERSION " cannot run this model" +
                  (input_size != graph_input_size ? " at " + std::to_string(input_size.width) +
                                                        "x" + std::to_string(input_size.height)
                                                  : std::string()) +
                  " (" + opencv_message(e) + ")"));
  }
}

int Detector::Impl::settle_format(const cv::Mat& output, const OnnxModelInfo& info) {
  const int classes_v8 = output.dims == 3 ? output.size[1] - 4 : 0;
  const int classes_x = output.dims == 3 ? output.size[2] - 5 : 0;
  const bool ultralytics = info.find("names") || info.find("stride");
  if (output.dims == 3 && output.size[0] == 1 && output.type() == CV_32F &&
      output.size[1] < output.size[2] && classes_v8 >= 1) {
    format = DetectorFormat::kYoloV8;
  } else if (output.dims == 3 && output.size[0] == 1 && output.type() == CV_32F &&
             output.size[1] > output.size[2] && classes_x >= 1 &&
             output.size[1] == yolox_anchor_count(input_size) && !ultralytics) {
    format = DetectorFormat::kYoloX;
  } else {
    throw InputError(
        file_error(path, "output shape " + describe_shape(output) +
                             " is neither YOLOv8 (1x(4+C)xN) nor YOLOX (1xNx(5+C) with N = " +
                             std::to_string(yolox_anchor_count(input_size)) + " for a " +
                             std::to_string(input_size.width) + "x" +
                             std::to_string(input_size.height) + " input)"));
  }
  return format == DetectorFormat::kYoloV8 ? classes_v8 : classes_x;
}

void Detector::Impl::settle_names(const OnnxModelInfo& info, int classes) {
  std::optional<std::vector<std::string>> declared;
  if (const auto text = info.find("names")) declared = parse_class_names(*text);
  if (declared && static_cast<int>(declared->size()) == classes) {
    names = std::move(*declared);
  } else if (classes == static_cast<int>(coco_class_names().size())) {
    names = coco_class_names();
  } else {
    for (int c = 0; c < classes; ++c) names.push_back("class" + std::to_string(c));
  }
}

Detector::Detector(const std::string& model_path, const DetectorOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = model_path;
  m.options = options;
  if (const auto problem = options.check()) throw InputError(*problem);
  check_model_file(model_path);
  const OnnxModelInfo info = read_onnx_info(model_path);
  if (const auto task = info.find("task"); task && *task != "detect")
    throw InputError(file_error(model_path, "Ultralytics task '" + *task +
                                                "' is not supported (a detect export is needed)"));
  m.load_network();
  m.settle_input_size(info);
  const cv::dnn::MatShape input_shape = {1, 3, m.input_size.height, m.input_size.width};
  try {
    m.adjusted = fix_trailing_broadcast_scales(m.net, input_shape);
  } catch (const cv::Exception&) {
    m.adjusted = 0;  // shape inference failed: the test forward below reports the problem
  }
  m.output_names = m.net.getUnconnectedOutLayersNames();
  if (m.output_names.empty()) throw InputError(file_error(model_path, "the network has no output"));
  const cv::Mat output = m.test_forward();
  const int classes = m.settle_format(output, info);
  m.settle_names(info, classes);
  m.allocate();
}

Detector::~Detector() = default;
Detector::Detector(Detector&&) noexcept = default;
Detector& Detector::operator=(Detector&&) noexcept = default;

std::vector<Detection> Detector::detect(const cv::Mat& bgr) const {
  if (!impl_ || bgr.empty() || bgr.type() != CV_8UC3) return {};
  try {
    const Letterbox lb = impl_->preprocess(bgr);
    impl_->forward(impl_->blob);
    return impl_->decode(lb, bgr.size());
  } catch (const cv::Exception&) {
    return {};
  }
}

DetectorFormat Detector::format() const { return impl_->format; }
cv::Size Detector::input_size() const { return impl_->input_size; }
const std::vector<std::string>& Detector::class_names() const { return impl_->names; }
const std::string& Detector::path() const { return impl_->path; }
int Detector::adjusted_layers() const { return impl_->adjusted; }
cv::Size Detector::graph_input_size() const { return impl_->graph_input_size; }

cv::Mat Detector::make_blob(const cv::Mat& bgr, Letterbox& letterbox) const {
  if (bgr.empty() || bgr.type() != CV_8UC3) return {};
  letterbox = impl_->preprocess(bgr);
  return impl_->blob.clone();
}

cv::Mat Detector::forward_blob(const cv::Mat& blob) const {
  impl_->forward(blob);
  return impl_->outputs.at(0).clone();
}

// --- drawing ------------------------------------------------------------------------------------

void draw_detections(cv::Mat& bgr, const std::vector<Detection>& detections,
                     const cv::Scalar& color) {
  if (bgr.empty() || bgr.type() != CV_8UC3) return;
  const int thickness = std::max(1, static_cast<int>(std::lround(bgr.cols / 320.0)));
  const double font_scale = std::max(0.4, bgr.cols / 1280.0);
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  // Dark text on a light box colour, light text on a dark one.
  const double luma = 0.114 * color[0] + 0.587 * color[1] + 0.299 * color[2];
  const cv::Scalar text_color = luma > 128.0 ? cv::Scalar(0, 0, 0) : cv::Scalar(255, 255, 255);
  for (const Detection& d : detections) {
    const cv::Rect box(
        cv::Point(static_cast<int>(std::lround(d.box.x)), static_cast<int>(std::lround(d.box.y))),
        cv::Point(static_cast<int>(std::lround(d.box.x + d.box.width)),
                  static_cast<int>(std::lround(d.box.y + d.box.height))));
    cv::rectangle(bgr, box, color, thickness, cv::LINE_8);
    char score[16];
    std::snprintf(score, sizeof score, " %.2f", static_cast<double>(d.score));
    const std::string label = d.class_name + score;
    int baseline = 0;
    const cv::Size text = cv::getTextSize(label, font, font_scale, 1, &baseline);
    // Above the box when there is room, else inside its top edge.
    const int top =
        box.y - text.height - baseline - 2 >= 0 ? box.y - text.height - baseline - 2 : box.y;
    const int left = std::clamp(box.x, 0, std::max(0, bgr.cols - text.width - 2));
    const cv::Rect background(left, top, text.width + 2, text.height + baseline + 2);
    cv::rectangle(bgr, background & cv::Rect(0, 0, bgr.cols, bgr.rows), color, cv::FILLED);
    cv::putText(bgr, label, cv::Point(left + 1, top + text.height + 1), font, font_scale,
                text_color, 1, cv::LINE_AA);
  }
}

}  // namespace mcslam::perception
