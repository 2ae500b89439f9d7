import json, subprocess, sys
base = open('topologies/ring3.toml').read()
attacks = [
 ("forge (outsider, +20 m in x)", 'kind = "forge"\ntarget = 0\nclaim = 1\nstart_s = 10.0\nbias = [20.0]'),
 ("tamper (on path, +20 m in x)", 'kind = "tamper"\ntarget = 0\nclaim = 1\nstart_s = 10.0\nbias = [20.0]'),
 ("replay (0.5 s later)", 'kind = "replay"\ntarget = 0\nclaim = 1\ndelay_s = 0.5'),
 ("flood (10,000 garbage datagrams/s)", 'kind = "flood"\ntarget = 0\nrate_hz = 10000.0'),
 ("false-data (insider, 1 m + 0.2 m/s)", 'kind = "false-data"\nnode = 1\nstart_s = 10.0\nbias = [1.0]\nramp = [0.2]'),
 ("false-data (insider, 0.05 m)", 'kind = "false-data"\nnode = 1\nstart_s = 10.0\nbias = [0.05]'),
]
def run(text, extra):
    open('/tmp/att/t.toml','w').write(text)
    out = subprocess.run(['./target/release/simnet','-t','/tmp/att/t.toml','--json']+extra, capture_output=True, text=True, check=True).stdout
    return json.loads(out)
rows = []
for name, a in attacks:
    text = base + "\n[[attack]]\n" + a + "\n"
    cells = []
    for extra in ([], ['--set','consensus.gate=0.999'], ['--auth'], ['--auth','--set','consensus.gate=0.999']):
        s = run(text, extra)
        e = s['attack_effect'][0]
        d = s['attacks'][0]['datagrams']
        rej = sum(d['rejected'].values())
        g = s['attacks'][0]['gated']; gc = s['attacks'][0].get('gated_clean')
        if d['used'] + d['ignored'] + rej == 0 and d['sent']:
            what = f"{d['sent']} sent"
        else:
            what = f"{d['sent']} sent, {d['used']} used, {rej} rejected"
        if '--set' in extra:
            what += f"; {g} gated ({gc} in the clean run)"
        cells.append(f"**{e['mean_error']:.4f}** m; {what}")
    rows.append(f"| {name} | " + " | ".join(cells) + " |")
print("| attack | no defence | gate only | key | key + gate |")
print("|---|---|---|---|---|")
print("\n".join(rows))
