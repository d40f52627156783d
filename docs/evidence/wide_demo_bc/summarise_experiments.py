# Per-seed success and mass by slope, and the slope-error table, from lhd experiment paper runs:
#   python3 summarise_experiments.py <evidence dir with experiment_seed{N}/> 0,1,2,3,4 [folder prefix]
# (the prefix of the per-seed folders, default experiment_seed; e.g. rlc_experiment_seed)
import csv,sys
E=sys.argv[1]; seeds=sys.argv[2].split(","); P=sys.argv[3] if len(sys.argv)>3 else "experiment_seed"
import collections
tab=collections.defaultdict(dict); err=collections.defaultdict(dict)
for s in seeds:
    for r in csv.DictReader(open(f"{E}/{P}{s}/table_controllers.csv")):
        if r["slope_deg"]=="all": continue
        k=float(r["slope_deg"]); d=tab[k].setdefault(s,[])
        d.append((float(r["success_rate"]), float(r["loaded_kg"] or 'nan'), int(r["attempts"])))
    for r in csv.DictReader(open(f"{E}/{P}{s}/table_slope_error.csv")):
        err[(float(r["slope_deg"]),float(r["error_deg"]))][s]=(float(r["success_rate"]), float(r["mass_change_pct"] or 'nan'), float(r["loaded_kg"] or 'nan'))
print("slope | per seed success (both materials) | mean kg")
for k in sorted(tab):
    vals=[]; kgs=[]
    for s in seeds:
        d=tab[k][s]; n=sum(a for _,_,a in d); vals.append(sum(sr*a for sr,_,a in d)/n); kgs+= [kg for _,kg,_ in d]
    print(k, " ".join(f"{v:.2f}" for v in vals), f"mean {sum(vals)/len(vals):.3f}", "kg", " ".join(f"{x:.1f}" for x in kgs))
print("slope error: success per seed / mass change %")
for k in sorted(err):
    print(k, " ".join(f"{err[k][s][0]:.2f}/{err[k][s][1]:+.0f}" for s in seeds), f"mean {sum(err[k][s][0] for s in seeds)/len(seeds):.3f}")
