// A Fast DDS participant that speaks ROS 2 on the wire, for testing mobmap_ros2 against
// a DDS implementation other than its own. It sends and receives samples as their CDR
// bytes under ROS 2's topic and type names and QoS, confined to the loopback interface
// (UDP on 127.0.0.1, no multicast, unicast peers on 127.0.0.1 only).
//
//   dds_peer --domain N --out DIR [--pace BYTES_PER_MS]   then commands on stdin, one per line:
//   pub NAME DDS_TOPIC TYPE QOS          a writer (QOS: sensor | reliable | latched | tf | tf_static | service)
//   sub NAME DDS_TOPIC TYPE QOS          a reader; each sample goes to DIR/NAME-<n>.cdr
//   send NAME FILE                       one sample, the file's bytes
//   play FEED.jsonl RATE [CLOCK]         a recording (write_bag.mjs --feed) at RATE x its pace on the
//                                        writers named by its ROS topics, /clock too when CLOCK is given
//   quit
// Events on stdout, one JSON object per line: {"event": "matched"|"sample"|"played"|"ok"|"error", ...}.
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/rtps/flowcontrol/FlowControllerDescriptor.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace eprosima::fastdds::dds;
using eprosima::fastrtps::rtps::IPLocator;
using eprosima::fastrtps::rtps::Locator_t;
using eprosima::fastrtps::rtps::SerializedPayload_t;

namespace {

std::mutex g_out;

void say(const nlohmann::json& j) {
  std::lock_guard<std::mutex> lock(g_out);
  std::cout << j.dump() << std::endl;
}

using Bytes = std::vector<std::uint8_t>;

/// Any type, as its CDR bytes (encapsulation header included).
class RawType : public TopicDataType {
 public:
  explicit RawType(const std::string& name) {
    setName(name.c_str());
    m_typeSize = 1u << 20;  // an initial payload; larger samples reallocate
    m_isGetKeyDefined = false;
    auto_fill_type_object(false);
    auto_fill_type_information(false);
  }
  bool serialize(void* data, SerializedPayload_t* payload) override {
    const Bytes& b = *static_cast<Bytes*>(data);
    if (b.size() < 4) return false;
    if (payload->max_size < b.size()) return false;
    std::memcpy(payload->data, b.data(), b.size());
    payload->length = static_cast<std::uint32_t>(b.size());
    payload->encapsulation = b[1] == 0 ? 0 : 1;  // CDR_BE : CDR_LE
    return true;
  }
  bool deserialize(SerializedPayload_t* payload, void* data) override {
    static_cast<Bytes*>(data)->assign(payload->data, payload->data + payload->length);
    return true;
  }
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data] { return static_cast<std::uint32_t>(static_cast<Bytes*>(data)->size()); };
  }
  void* createData() override { return new Bytes(); }
  void deleteData(void* data) override { delete static_cast<Bytes*>(data); }
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) override { return false; }
};

struct Qos {
  bool reliable, transient_local;
  int depth;
};

Qos qosNamed(const std::string& q) {
  if (q == "sensor") return {false, false, 5};
  if (q == "reliable") return {true, false, 10};
  if (q == "latched") return {true, true, 1};
  if (q == "tf") return {true, false, 100};
  if (q == "tf_static") return {true, true, 1};
  if (q == "service") return {true, false, 10};
  throw std::invalid_argument("unknown QoS " + q);
}

/// A writer's or a reader's QoS as ROS 2's profile `q` sets it.
template <typename EndpointQos>
void apply(EndpointQos& e, const Qos& q) {
  e.reliability().kind = q.reliable ? RELIABLE_RELIABILITY_QOS : BEST_EFFORT_RELIABILITY_QOS;
  e.durability().kind = q.transient_local ? TRANSIENT_LOCAL_DURABILITY_QOS : VOLATILE_DURABILITY_QOS;
  e.history().kind = KEEP_LAST_HISTORY_QOS;
  e.history().depth = q.depth;
  e.endpoint().history_memory_policy = eprosima::fastrtps::rtps::DYNAMIC_REUSABLE_MEMORY_MODE;
}

class Peer : public DataWriterListener {
 public:
  /// `pace`: at most this many bytes a millisecond leave each writer (0: as fast as they
  /// come). A receiver whose socket buffer the host caps (net.core.rmem_max) loses most
  /// fragments of a burst; a paced peer lets the tests judge mapping, not the host.
  Peer(int domain, std::string out, int pace) : out_(std::move(out)) {
    DomainParticipantQos pq;
    pq.name("mobmap_test_peer");
    if (pace > 0) {
      auto paced = std::make_shared<eprosima::fastdds::rtps::FlowControllerDescriptor>();
      paced->name = kPaced;
      paced->max_bytes_per_period = pace;
      paced->period_ms = 1;
      pq.flow_controllers().push_back(paced);
      paced_ = true;
    }
    // Loopback only: one UDP transport on 127.0.0.1, discovery by unicast to 127.0.0.1.
    pq.transport().use_builtin_transports = false;
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    udp->interfaceWhiteList.emplace_back("127.0.0.1");
    udp->sendBufferSize = udp->receiveBufferSize = 8u << 20;
    pq.transport().user_transports.push_back(udp);
    Locator_t loopback;
    IPLocator::setIPv4(loopback, 127, 0, 0, 1);
    pq.wire_protocol().builtin.initialPeersList.push_back(loopback);
    pq.wire_protocol().builtin.metatrafficUnicastLocatorList.push_back(loopback);
    pq.wire_protocol().default_unicast_locator_list.push_back(loopback);
    participant_ = DomainParticipantFactory::get_instance()->create_participant(domain, pq);
    if (!participant_) throw std::runtime_error("cannot create a Fast DDS participant");
    publisher_ = participant_->create_publisher(PUBLISHER_QOS_DEFAULT);
    subscriber_ = participant_->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
  }

  ~Peer() override {
    participant_->delete_contained_entities();
    DomainParticipantFactory::get_instance()->delete_participant(participant_);
  }

  Topic* topic(const std::string& name, const std::string& type) {
    if (!participant_->find_type(type)) TypeSupport(new RawType(type)).register_type(participant_);
    auto it = topics_.find(name);
    if (it != topics_.end()) return it->second;
    Topic* t = participant_->create_topic(name, type, TOPIC_QOS_DEFAULT);
    if (!t) throw std::runtime_error("cannot create topic " + name + " of " + type);
    topics_[name] = t;
    return t;
  }

  void pub(const std::string& name, const std::string& dds_topic, const std::string& type, const std::string& qos) {
    DataWriterQos wq = DATAWRITER_QOS_DEFAULT;
    apply(wq, qosNamed(qos));
    wq.publish_mode().kind = ASYNCHRONOUS_PUBLISH_MODE;  // large samples go out in fragments
    if (paced_) wq.publish_mode().flow_controller_name = kPaced;
    DataWriter* w = publisher_->create_datawriter(topic(dds_topic, type), wq, this);
    if (!w) throw std::runtime_error("cannot write " + dds_topic);
    std::lock_guard<std::mutex> lock(mutex_);
    writers_[name] = w;
    names_[w] = name;
    // A match may come while the writer is being created, before it has a name.
    auto early = early_.find(w);
    if (early != early_.end()) say({{"event", "matched"}, {"name", name}, {"count", early->second}});
  }

  void sub(const std::string& name, const std::string& dds_topic, const std::string& type, const std::string& qos) {
    DataReaderQos rq = DATAREADER_QOS_DEFAULT;
    apply(rq, qosNamed(qos));
    auto listener = std::make_unique<Listener>(this, name);
    DataReader* r = subscriber_->create_datareader(topic(dds_topic, type), rq, listener.get());
    if (!r) throw std::runtime_error("cannot read " + dds_topic);
    std::lock_guard<std::mutex> lock(mutex_);
    listeners_.push_back(std::move(listener));
  }

  void send(const std::string& name, const Bytes& bytes) {
    DataWriter* w = nullptr;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = writers_.find(name);
      if (it == writers_.end()) throw std::runtime_error("no writer " + name);
      w = it->second;
    }
    Bytes copy = bytes;
    if (!w->write(&copy)) throw std::runtime_error("write refused on " + name);
  }

  bool has(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    return writers_.count(name) > 0;
  }

  void on_publication_matched(DataWriter* w, const PublicationMatchedStatus& s) override {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = names_.find(w);
    if (it == names_.end()) {
      early_[w] = s.current_count;
    } else {
      say({{"event", "matched"}, {"name", it->second}, {"count", s.current_count}});
    }
  }

 private:
  class Listener : public DataReaderListener {
   public:
    Listener(Peer* peer, std::string name) : peer_(peer), name_(std::move(name)) {}
    void on_data_available(DataReader* r) override {
      Bytes b;
      SampleInfo info;
      while (r->take_next_sample(&b, &info) == ReturnCode_t::RETCODE_OK) {
        if (!info.valid_data) continue;
        const std::string path = peer_->out_ + "/" + name_ + "-" + std::to_string(n_) + ".cdr";
        {
          std::ofstream f(path + ".part", std::ios::binary);
          f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
        }
        std::rename((path + ".part").c_str(), path.c_str());
        say({{"event", "sample"}, {"name", name_}, {"n", n_}, {"size", b.size()}, {"path", path}});
        ++n_;
      }
    }
    void on_subscription_matched(DataReader*, const SubscriptionMatchedStatus& s) override {
      say({{"event", "matched"}, {"name", name_}, {"count", s.current_count}});
    }

   private:
    Peer* peer_;
    std::string name_;
    int n_ = 0;
  };

  std::string out_;
  static constexpr const char* kPaced = "mobmap_test_paced";
  bool paced_ = false;
  DomainParticipant* participant_ = nullptr;
  Publisher* publisher_ = nullptr;
  Subscriber* subscriber_ = nullptr;
  std::map<std::string, Topic*> topics_;
  std::mutex mutex_;
  std::map<std::string, DataWriter*> writers_;
  std::map<DataWriter*, std::string> names_;
  std::map<DataWriter*, int> early_;
  std::vector<std::unique_ptr<Listener>> listeners_;
};

Bytes base64(const std::string& s) {
  static const std::string chars = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  Bytes out;
  unsigned v = 0;
  int bits = 0;
  for (const char c : s) {
    if (c == '=') break;
    const auto k = chars.find(c);
    if (k == std::string::npos) continue;
    v = (v << 6) | static_cast<unsigned>(k);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<std::uint8_t>((v >> bits) & 0xff));
    }
  }
  return out;
}

Bytes clockSample(std::int64_t ns) {
  Bytes b = {0, 1, 0, 0};
  const std::int32_t sec = static_cast<std::int32_t>(ns / 1000000000);
  const std::uint32_t nsec = static_cast<std::uint32_t>(ns % 1000000000);
  b.resize(12);
  std::memcpy(b.data() + 4, &sec, 4);
  std::memcpy(b.data() + 8, &nsec, 4);
  return b;
}

/// Plays a write_bag.mjs feed at `rate` times its pace on the writers named by its ROS topics.
int play(Peer& peer, const std::string& feed, double rate, bool clock) {
  std::ifstream f(feed);
  if (!f) throw std::runtime_error("cannot read " + feed);
  std::string line;
  std::int64_t t0 = -1;
  const auto start = std::chrono::steady_clock::now();
  int sent = 0;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    const auto m = nlohmann::json::parse(line);
    const std::string topic = m["topic"];
    const std::int64_t t = std::stoll(m["t"].get<std::string>());
    if (t0 < 0) t0 = t;
    const auto due = start + std::chrono::nanoseconds(static_cast<std::int64_t>(static_cast<double>(t - t0) / rate));
    std::this_thread::sleep_until(due);
    if (clock) peer.send("clock", clockSample(t));
    if (!peer.has(topic)) continue;
    peer.send(topic, base64(m["data"]));
    ++sent;
  }
  return sent;
}

}  // namespace

int main(int argc, char** argv) {
  int domain = 0;
  std::string out = ".";
  int pace = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--domain") == 0) domain = std::atoi(argv[i + 1]);
    if (std::strcmp(argv[i], "--out") == 0) out = argv[i + 1];
    if (std::strcmp(argv[i], "--pace") == 0) pace = std::atoi(argv[i + 1]);
  }
  try {
    Peer peer(domain, out, pace);
    std::string line;
    while (std::getline(std::cin, line)) {
      std::istringstream in(line);
      std::string cmd;
      in >> cmd;
      try {
        if (cmd == "pub" || cmd == "sub") {
          std::string name, topic, type, qos;
          in >> name >> topic >> type >> qos;
          if (cmd == "pub") {
            peer.pub(name, topic, type, qos);
          } else {
            peer.sub(name, topic, type, qos);
          }
          say({{"event", "ok"}, {"command", cmd}, {"name", name}});
        } else if (cmd == "send") {
          std::string name, file;
          in >> name >> file;
          std::ifstream f(file, std::ios::binary);
          const Bytes b((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
          peer.send(name, b);
          say({{"event", "ok"}, {"command", cmd}, {"name", name}, {"size", b.size()}});
        } else if (cmd == "play") {
          std::string feed, clock;
          double rate = 1.0;
          in >> feed >> rate >> clock;
          const int sent = play(peer, feed, rate, !clock.empty());
          say({{"event", "played"}, {"sent", sent}});
        } else if (cmd == "quit") {
          break;
        } else if (!cmd.empty()) {
          say({{"event", "error"}, {"what", "unknown command " + cmd}});
        }
      } catch (const std::exception& e) {
        say({{"event", "error"}, {"what", e.what()}});
      }
    }
  } catch (const std::exception& e) {
    say({{"event", "error"}, {"what", e.what()}});
    return 1;
  }
  return 0;
}
