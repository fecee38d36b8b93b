#include "dds.hpp"

#include <dds/ddsi/ddsi_serdata.h>

#include <stdexcept>

namespace mobmap::ros2 {
namespace {

dds_entity_t check(dds_entity_t e, const std::string& what) {
  if (e < 0) throw DdsError(what + ": " + dds_strretcode(e));
  return e;
}

/// Cyclone's QoS for `q`.
struct QosHandle {
  dds_qos_t* q = dds_create_qos();
  explicit QosHandle(const Qos& qos) {
    dds_qset_reliability(q, qos.reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT, DDS_MSECS(100));
    dds_qset_durability(q, qos.transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, qos.depth);
  }
  ~QosHandle() { dds_delete_qos(q); }
  QosHandle(const QosHandle&) = delete;
  QosHandle& operator=(const QosHandle&) = delete;
};

}  // namespace

std::string Qos::describe() const {
  return std::string(reliable ? "reliable" : "best effort") + ", " + (transient_local ? "transient local" : "volatile") +
         ", keep last " + std::to_string(depth);
}

Qos sensorQos() { return {false, false, 5}; }
Qos latchedQos() { return {true, true, 1}; }
Qos tfQos() { return {true, false, 100}; }
Qos tfStaticQos() { return {true, true, 100}; }
Qos serviceQos() { return {true, false, 10}; }

Participant::Participant(std::uint32_t domain_id, const std::string& config) {
  domain_ = check(dds_create_domain(domain_id, config.c_str()), "cannot join DDS domain " + std::to_string(domain_id));
  const dds_entity_t p = dds_create_participant(domain_id, nullptr, nullptr);
  if (p < 0) {
    dds_delete(domain_);
    check(p, "cannot create a DDS participant in domain " + std::to_string(domain_id));
  }
  participant_ = p;
}

Participant::~Participant() {
  if (participant_ > 0) dds_delete(participant_);
  if (domain_ > 0) dds_delete(domain_);
}

dds_entity_t Participant::topic(const dds_topic_descriptor_t* type, const std::string& name) {
  for (const auto& [n, t] : topics_) {
    if (n == name) return t;
  }
  const dds_entity_t t = check(dds_create_topic(participant_, type, name.c_str(), nullptr, nullptr), "cannot create topic " + name);
  topics_.emplace_back(name, t);
  return t;
}

RawReader::RawReader(Participant& p, const dds_topic_descriptor_t* type, const std::string& topic, const Qos& qos, Handler handler)
    : topic_(topic), type_name_(type->m_typename), handler_(std::move(handler)) {
  QosHandle q(qos);
  reader_ = check(dds_create_reader(p.handle(), p.topic(type, topic), q.q, nullptr), "cannot read " + topic);
  dds_set_status_mask(reader_, DDS_DATA_AVAILABLE_STATUS);
  condition_ = check(dds_create_readcondition(reader_, DDS_ANY_STATE), "cannot wait on " + topic);
}

RawReader::~RawReader() {
  if (reader_ > 0) dds_delete(reader_);
}

int RawReader::takeAll() {
  int n = 0;
  for (;;) {
    struct ddsi_serdata* sd = nullptr;
    dds_sample_info_t info;
    const dds_return_t got = dds_takecdr(reader_, &sd, 1, &info, DDS_ANY_STATE);
    if (got <= 0) return n;
    if (info.valid_data) {
      const std::uint32_t size = ddsi_serdata_size(sd);
      buffer_.resize(size);
      if (size > 0) ddsi_serdata_to_ser(sd, 0, size, buffer_.data());
      ddsi_serdata_unref(sd);
      ++n;
      handler_(*this, buffer_.data(), buffer_.size());
      if (buffer_.capacity() > (64u << 20)) std::vector<std::uint8_t>().swap(buffer_);  // a rare huge sample is not kept
    } else {
      ddsi_serdata_unref(sd);
    }
  }
}

std::uint32_t RawReader::lost() const {
  dds_sample_lost_status_t s{};
  return dds_get_sample_lost_status(reader_, &s) == DDS_RETCODE_OK ? s.total_count : 0;
}

std::int32_t RawReader::matched() const {
  dds_subscription_matched_status_t s{};
  return dds_get_subscription_matched_status(reader_, &s) == DDS_RETCODE_OK ? static_cast<std::int32_t>(s.current_count) : 0;
}

std::uint32_t RawReader::incompatible() const {
  dds_requested_incompatible_qos_status_t s{};
  return dds_get_requested_incompatible_qos_status(reader_, &s) == DDS_RETCODE_OK ? s.total_count : 0;
}

Writer::Writer(Participant& p, const dds_topic_descriptor_t* type, const std::string& topic, const Qos& qos) : topic_(topic) {
  QosHandle q(qos);
  writer_ = check(dds_create_writer(p.handle(), p.topic(type, topic), q.q, nullptr), "cannot write " + topic);
}

Writer::~Writer() {
  if (writer_ > 0) dds_delete(writer_);
}

void Writer::write(const void* sample) {
  const dds_return_t r = dds_write(writer_, sample);
  if (r != DDS_RETCODE_OK) throw DdsError("cannot write on " + topic_ + ": " + dds_strretcode(r));
}

std::int32_t Writer::matched() const {
  dds_publication_matched_status_t s{};
  return dds_get_publication_matched_status(writer_, &s) == DDS_RETCODE_OK ? static_cast<std::int32_t>(s.current_count) : 0;
}

PublicationWatch::PublicationWatch(Participant& p, Handler handler) : handler_(std::move(handler)) {
  reader_ = check(dds_create_reader(p.handle(), DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr), "cannot watch publications");
  condition_ = check(dds_create_readcondition(reader_, DDS_ANY_STATE), "cannot wait on publications");
}

PublicationWatch::~PublicationWatch() {
  if (reader_ > 0) dds_delete(reader_);
}

int PublicationWatch::takeAll() {
  int n = 0;
  for (;;) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    const dds_return_t got = dds_take(reader_, samples, &info, 1, 1);
    if (got <= 0) return n;
    const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[0]);
    if (info.instance_state != DDS_IST_ALIVE) {
      // Gone (its writer or its participant left, or its lease ran out): only the key remains.
      handler_(Publication{"", "", false});
    } else if (info.valid_data && e && e->topic_name && e->type_name) {
      handler_(Publication{e->topic_name, e->type_name, true});
    }
    dds_return_loan(reader_, samples, got);
    ++n;
  }
}

WaitSet::WaitSet(Participant& p) {
  waitset_ = check(dds_create_waitset(p.handle()), "cannot create a waitset");
  guard_ = check(dds_create_guardcondition(p.handle()), "cannot create a guard condition");
  dds_waitset_attach(waitset_, guard_, guard_);
}

WaitSet::~WaitSet() {
  if (waitset_ > 0) dds_delete(waitset_);
  if (guard_ > 0) dds_delete(guard_);
}

void WaitSet::attach(dds_entity_t condition) {
  const dds_return_t r = dds_waitset_attach(waitset_, condition, condition);
  if (r != DDS_RETCODE_OK) throw DdsError(std::string("cannot wait on a condition: ") + dds_strretcode(r));
}

bool WaitSet::wait(int timeout_ms) {
  const dds_return_t r = dds_waitset_wait(waitset_, nullptr, 0, DDS_MSECS(timeout_ms));
  dds_set_guardcondition(guard_, false);
  return r > 0;
}

void WaitSet::wake() { dds_set_guardcondition(guard_, true); }

}  // namespace mobmap::ros2
