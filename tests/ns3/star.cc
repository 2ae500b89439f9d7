// A star of N senders around a coordinator on one lr-wpan channel: unslotted CSMA/CA, each sender one
// `payload`-octet packet every `period` seconds, all at the same instants, unacknowledged or (--ack=1) with ACKs and
// macMaxFrameRetries 3. Prints N, sent, received (distinct packets: a frame received again after its ACK was lost
// counts once).
#include "ns3/core-module.h"
#include "ns3/lr-wpan-module.h"
#include "ns3/mobility-module.h"
#include "ns3/propagation-module.h"
#include "ns3/spectrum-module.h"
#include <cmath>
#include <iostream>
#include <map>
#include <set>
#include <vector>
#include <utility>

using namespace ns3;
using namespace ns3::lrwpan;

static std::set<std::pair<uint16_t, uint32_t>> g_received;
static bool g_ack = false;
// Each sender's packets in order: its k-th packet carries sequence number k (the MAC's DSN wraps at 256).
static std::map<uint32_t, uint32_t> g_next;

static void Received(McpsDataIndicationParams params, Ptr<Packet> p) {
    uint8_t buf[4] = {0, 0, 0, 0};
    p->CopyData(buf, 4);
    uint32_t seq = buf[0] | (buf[1] << 8) | (buf[2] << 16) | (uint32_t(buf[3]) << 24);
    uint8_t addr[2];
    params.m_srcAddr.CopyTo(addr);
    g_received.insert({uint16_t(addr[0] << 8 | addr[1]), seq});
}

static void Send(Ptr<LrWpanNetDevice> dev, uint32_t id, uint32_t payload) {
    McpsDataRequestParams params;
    params.m_srcAddrMode = SHORT_ADDR;
    params.m_dstAddrMode = SHORT_ADDR;
    params.m_dstPanId = 0;
    params.m_dstAddr = Mac16Address("00:01");
    params.m_msduHandle = 0;
    params.m_txOptions = g_ack ? TX_OPTION_ACK : 0;
    std::vector<uint8_t> body(payload, 0);
    uint32_t seq = g_next[id]++;
    for (int b = 0; b < 4 && b < int(payload); b++) {
        body[b] = uint8_t(seq >> (8 * b));
    }
    dev->GetMac()->McpsDataRequest(params, Create<Packet>(body.data(), payload));
}

int main(int argc, char** argv) {
    uint32_t n = 3, payload = 50, run = 1, ack = 0;
    double period = 0.05, seconds = 10.0, radius = 5.0;
    CommandLine cmd;
    cmd.AddValue("n", "senders", n);
    cmd.AddValue("payload", "octets", payload);
    cmd.AddValue("period", "s", period);
    cmd.AddValue("seconds", "s", seconds);
    cmd.AddValue("radius", "m", radius);
    cmd.AddValue("run", "run number", run);
    cmd.AddValue("ack", "1: acknowledged, with retries", ack);
    cmd.Parse(argc, argv);
    g_ack = ack != 0;
    RngSeedManager::SetSeed(1);
    RngSeedManager::SetRun(run);
    Ptr<SingleModelSpectrumChannel> channel = CreateObject<SingleModelSpectrumChannel>();
    channel->AddPropagationLossModel(CreateObject<LogDistancePropagationLossModel>());
    std::vector<Ptr<LrWpanNetDevice>> devs;
    for (uint32_t i = 0; i <= n; i++) {
        Ptr<Node> node = CreateObject<Node>();
        Ptr<LrWpanNetDevice> dev = CreateObject<LrWpanNetDevice>();
        char addr[8];
        std::snprintf(addr, sizeof addr, "00:%02x", i + 1);
        dev->SetAddress(Mac16Address(addr));
        dev->SetChannel(channel);
        node->AddDevice(dev);
        Ptr<ConstantPositionMobilityModel> mob = CreateObject<ConstantPositionMobilityModel>();
        double a = i == 0 ? 0 : 2 * M_PI * (i - 1) / n;
        mob->SetPosition(i == 0 ? Vector(0, 0, 0) : Vector(radius * std::cos(a), radius * std::sin(a), 0));
        dev->GetPhy()->SetMobility(mob);
        dev->GetPhy()->SetRxSensitivity(-95.0);
        devs.push_back(dev);
    }
    devs[0]->GetMac()->SetMcpsDataIndicationCallback(MakeCallback(&Received));
    uint32_t sent = 0;
    for (double t = 0.001; t < seconds; t += period) {
        for (uint32_t i = 1; i <= n; i++) {
            Simulator::Schedule(Seconds(t), &Send, devs[i], i, payload);
            sent++;
        }
    }
    Simulator::Stop(Seconds(seconds + 1));
    Simulator::Run();
    std::cout << n << " " << sent << " " << g_received.size() << std::endl;
    Simulator::Destroy();
    return 0;
}
