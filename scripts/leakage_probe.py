#!/usr/bin/env python3
"""Leakage probe: a mode in the 275-325 Hz band beside a stronger, slower mode 1.5-3.5 band
widths away (bands 75-575 Hz, 50 Hz wide), each front end; counts the 275-325 Hz band's T60s
off by more than 5 % with and without a flag.

usage: scripts/leakage_probe.py DAMPSCOPE_BINARY SEED CASES
Random: the own mode's frequency 285-315 Hz and T60 0.25-1 s; the other mode's T60 1.5-8x
longer, its amplitude 0-25 dB above, its phase random. Writes leakage_probe.wav in the temporary directory.
"""
import subprocess, random, sys, csv, io, math, os, tempfile
WAV=os.path.join(tempfile.gettempdir(), 'leakage_probe.wav')
B=sys.argv[1]; seed=int(sys.argv[2]); n=int(sys.argv[3])
rng=random.Random(seed)
fes=[("octave",[]),("goyder",[]),("stft",["--window-ms","50"])]
stats={fe:[0,0,0,0.0] for fe,_ in fes}  # numbers, unflagged>5%, flagged-with-number>5%, max unflagged err
bad=[]
for i in range(n):
    fs=4096
    fa=rng.uniform(285,315)
    side=rng.choice([-1,1])
    fb=300+side*rng.uniform(1.5,3.5)*50
    ta=rng.uniform(0.25,1.0); tb=ta*rng.uniform(1.5,8)
    Da=1.1/(ta*fa); Db=1.1/(tb*fb)
    amp=10**(rng.uniform(0,25)/20)
    ph=rng.uniform(0,360)
    sec=min(6, max(3, 1.5*tb))
    subprocess.run([B,"synth","--mode",f"{fa}:{Da}:1:0","--mode",f"{fb}:{Db}:{amp}:{ph}","--fs",str(fs),"--seconds",str(sec),"--out",WAV],check=True,stderr=subprocess.DEVNULL)
    for fe,extra in fes:
        out=subprocess.run([B,"analyze",WAV,"--front-end",fe,"--bands","75:575:50"]+extra,capture_output=True,text=True).stdout
        rows=list(csv.DictReader(io.StringIO(out)))
        r=[x for x in rows if x["f_lo"].startswith("275")][0]
        if r["damping_ratio"]:
            err=float(r["t60_s"])/ta-1
            st=stats[fe]; st[0]+=1
            if abs(err)>0.05:
                if r["flags"]: st[2]+=1
                else:
                    st[1]+=1; bad.append((fe,round(fa,1),round(fb,1),round(ta,2),round(tb,2),round(20*math.log10(amp),1),round(err*100,1)))
            if not r["flags"]: st[3]=max(st[3],abs(err))
for fe in stats: print(fe, "numbers %d, unflagged >5%%: %d, flagged >5%%: %d, max unflagged |err| %.1f%%"%(stats[fe][0],stats[fe][1],stats[fe][2],100*stats[fe][3]))
for b in bad[:20]: print(b)
