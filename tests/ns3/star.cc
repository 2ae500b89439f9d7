// A star of N senders around a coordinator on one lr-wpan channel: unslotted CSMA/CA, no ACK, each sender one
// `payload`-octet packet every `period` seconds, all at the same instants. Prints N, sent, received.
#include "ns3/core-module.h"
#include "ns3/lr-wpan-module.h"
#include "ns3/mobility-module.h"
#include "ns3/propagation-module.h"
#include "ns3/spectrum-module.h"
#include <cmath>
#include <iostream>

using namespace ns3;
using namespace ns3::lrwpan;

static uint32_t g_received = 0;

static void Received(McpsDataIndicationParams, Ptr<Packet>) { g_received++; }

static void Send(Ptr<LrWpanNetDevice> dev, uint32_t payload) {
    McpsDataRequestParams params;
    params.m_srcAddrMode = SHORT_ADDR;
    params.m_dstAddrMode = SHORT_ADDR;
    params.m_dstPanId = 0;
    params.m_dstAddr = Mac16Address("00:01");
    params.m_msduHandle = 0;
    params.m_txOptions = 0;
    dev->GetMac()->McpsDataRequest(params, Create<Packet>(payload));
}

int main(int argc, char** argv) {
    uint32_t n = 3, payload = 50, run = 1;
    double period = 0.05, seconds = 10.0, radius = 5.0;
    CommandLine cmd;
    cmd.AddValue("n", "senders", n);
    cmd.AddValue("payload", "octets", payload);
    cmd.AddValue("period", "s", period);
    cmd.AddValue("seconds", "s", seconds);
    cmd.AddValue("radius", "m", radius);
    cmd.AddValue("run", "run number", run);
    cmd.Parse(argc, argv);
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
            Simulator::Schedule(Seconds(t), &Send, devs[i], payload);
            sent++;
        }
    }
    Simulator::Stop(Seconds(seconds + 1));
    Simulator::Run();
    std::cout << n << " " << sent << " " << g_received << std::endl;
    Simulator::Destroy();
    return 0;
}
