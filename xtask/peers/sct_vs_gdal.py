#!/usr/bin/env python3
"""How a .sct model compares in size with GDAL's lossy rasters, measured (issue 45).

  python xtask/peers/sct_vs_gdal.py [RELIEF]   (default RELIEF: target/release/relief)

Compresses the bundled fixtures/grandcanyon.tif with `relief compress` (default, --quantize,
--sparsity 8), decompresses it, and compares with GDAL (gdal_translate on PATH): LERC_DEFLATE
GeoTIFF at the same maximum error and at the same RMSE, and JPEG 2000 (OpenJPEG, 16-bit scaled)
at the same bytes. Needs numpy. Prints one line per setting.
"""
import subprocess, os, sys, tempfile, numpy as np
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
R = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, 'target', 'release', 'relief')
SRC = os.path.join(ROOT, 'fixtures', 'grandcanyon.tif')
D = tempfile.mkdtemp(prefix='sct_vs_gdal-')
def sh(*a): return subprocess.run(a, capture_output=True, text=True, check=True).stdout
def read(path):
    out=os.path.join(D,'tmp_read'); sh('gdal_translate','-q','-of','ENVI','-ot','Float64',path,out)
    n=512; a=np.fromfile(out,'<f8').reshape(n,n); return a
T=read(SRC); rng=T.max()-T.min()
def err(a): e=a-T; rmse=np.sqrt((e**2).mean()); return rmse, np.abs(e).max(), 20*np.log10(rng/rmse)
raw=T.size*4
rows=[]
for tag,flags in [('sct default',[]),('sct --quantize',['--quantize']),('sct --sparsity 8',['--sparsity','8'])]:
    s=os.path.join(D,'m.sct'); o=os.path.join(D,'m.tif')
    sh(R,'compress',SRC,s,'--force','-q',*flags); sh(R,'decompress',s,o,'--force','-q')
    b=os.path.getsize(s); rmse,mx,psnr=err(read(o))
    # LERC at the same max error and at the same RMSE (uniform error: rmse = e/sqrt(3))
    out={}
    for name,z in [('max',mx),('rmse',rmse*np.sqrt(3))]:
        l=os.path.join(D,'l.tif'); sh('gdal_translate','-q','-ot','Float32','-co','COMPRESS=LERC_DEFLATE','-co',f'MAX_Z_ERROR={z}',SRC,l)
        lb=os.path.getsize(l); lr,lm,lp=err(read(l)); out[name]=(lb,lr,lm)
    # JPEG 2000 at the same bytes: 16-bit scaled, QUALITY = percentage of the 16-bit raw size
    lo,hi=T.min(),T.max()
    u=os.path.join(D,'u16.tif'); sh('gdal_translate','-q','-ot','UInt16','-scale',str(lo),str(hi),'0','65535',SRC,u)
    q=100.0*b/(T.size*2); j=os.path.join(D,'j.jp2')
    if q >= 100:
        print(f"{tag}: {b} B, RMSE {rmse:.2f} m, max {mx:.1f} m, PSNR {psnr:.1f} dB | LERC same max error: {out['max'][0]} B ({b/out['max'][0]:.1f}x smaller), same RMSE: {out['rmse'][0]} B ({b/out['rmse'][0]:.1f}x) | larger than the 16-bit raster itself")
        continue
    sh('gdal_translate','-q','-of','JP2OpenJPEG','-co',f'QUALITY={min(q,100):.4f}','-co','REVERSIBLE=NO',u,j)
    jb=os.path.getsize(j); J=read(j)*(hi-lo)/65535+lo; jr,jm,jp=err(J)
    print(f"{tag}: {b} B, RMSE {rmse:.2f} m, max {mx:.1f} m, PSNR {psnr:.1f} dB | LERC same max error: {out['max'][0]} B ({b/out['max'][0]:.1f}x smaller), same RMSE: {out['rmse'][0]} B (RMSE {out['rmse'][1]:.2f}, {b/out['rmse'][0]:.1f}x) | JPEG2000 {jb} B: RMSE {jr:.3f} m, PSNR {jp:.1f} dB ({jp-psnr:+.1f} dB)")
print(f"input: 512x512 Int16, {os.path.getsize(SRC)} B as given (DEFLATE GeoTIFF), relief {rng:.0f} m")
