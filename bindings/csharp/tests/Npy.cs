// A float32 C-order .npy reader shared by the C# test programs (tests/csharp.rs compiles it in).
using System;
using System.Collections.Generic;
using System.IO;
using System.Text;

static class Npy
{
    /// <summary>A float32 C-order .npy file: its shape and values.</summary>
    public static float[] Read(string path, out int[] shape)
    {
        byte[] bytes = File.ReadAllBytes(path);
        int headerLen = bytes[8] | (bytes[9] << 8);
        string header = Encoding.ASCII.GetString(bytes, 10, headerLen);
        if (!header.Contains("'<f4'") || header.Contains("'fortran_order': True"))
            throw new Exception(path + ": not a C-order float32 .npy");
        string dims = header.Substring(header.IndexOf('(') + 1);
        dims = dims.Substring(0, dims.IndexOf(')'));
        var parts = new List<int>();
        foreach (string d in dims.Split(','))
            if (d.Trim().Length > 0) parts.Add(int.Parse(d.Trim()));
        shape = parts.ToArray();
        int offset = 10 + headerLen;
        var values = new float[(bytes.Length - offset) / 4];
        Buffer.BlockCopy(bytes, offset, values, 0, values.Length * 4);
        return values;
    }
}
