# Draws docs/media/reach_volume.png: the reach volume of punch_core::spec::REACH_VOLUME (its numbers, copied
# here) around the character. Run from the repository root: .venv/bin/python docs/media/reach_volume.py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import Rectangle, Circle
d=(0.60,0.85); h=(1.15,1.55); s=(-0.25,0.25)
fig,(side,top)=plt.subplots(1,2,figsize=(10,4.2))
# side view: z ahead (x axis), y up
side.add_patch(Rectangle((d[0],h[0]),d[1]-d[0],h[1]-h[0],alpha=0.25,color="tab:green",label="reach volume (target centres)"))
side.plot([0,0],[0,1.056],color="gray",lw=6,alpha=0.5); side.plot([0,0],[1.056,1.42],color="gray",lw=10,alpha=0.5)
side.add_patch(Circle((0,1.62),0.1,color="gray",alpha=0.5))
side.add_patch(Circle((0,1.42),0.619,fill=False,ls="--",color="tab:blue",label="arm's length from the shoulder (0.619 m)"))
side.plot(0.72,1.35,"k*",ms=12,label="default placement (0.72, 1.35, 0)")
side.add_patch(Rectangle((0.72-0.175,1.35-0.5),0.35,1.0,fill=False,color="k",alpha=0.4,label="the sandbag at the default placement"))
side.set_xlim(-0.3,1.3); side.set_ylim(0,2.0); side.set_aspect("equal"); side.grid(alpha=0.3)
side.set_xlabel("ahead, +Z (m)"); side.set_ylabel("height, +Y (m)"); side.set_title("side view (the character faces right)")
side.legend(fontsize=7,loc="lower right")
# top view: z ahead (y axis), x left (x axis reversed so the character's right is on the right)
top.add_patch(Rectangle((s[0],d[0]),s[1]-s[0],d[1]-d[0],alpha=0.25,color="tab:green"))
for x in (0.18,-0.18):
    top.add_patch(Circle((x,0),0.619,fill=False,ls="--",color="tab:blue"))
    top.plot(x,0,"o",color="gray")
top.add_patch(Rectangle((-0.2,-0.1),0.4,0.2,color="gray",alpha=0.5))
top.plot(0,0.72,"k*",ms=12)
top.set_xlim(0.9,-0.9); top.set_ylim(-0.3,1.3); top.set_aspect("equal"); top.grid(alpha=0.3)
top.set_xlabel("side, +X = the character's left (m)"); top.set_ylabel("ahead, +Z (m)"); top.set_title("top view (seen from above, behind the character)")
fig.suptitle("Reach volume: 0.60-0.85 m ahead, 1.15-1.55 m high, 0.25 m to either side; bag up to 1 m/s; any start pose")
fig.tight_layout(); fig.savefig("docs/media/reach_volume.png",dpi=100)
