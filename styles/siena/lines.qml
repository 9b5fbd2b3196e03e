<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>
<qgis version="3.22.0-Białowieża" styleCategories="Symbology|Labeling" labelsEnabled="0">
  <renderer-v2 type="categorizedSymbol" attr="code" symbollevels="0" enableorderby="0" forceraster="0" referencescale="-1">
    <categories>
      <category value="CUR01001" symbol="0" render="true" label="CURVA_DIRETTRICE curva di livello direttrice" />
      <category value="MAR01001" symbol="1" render="true" label="BORDO_STRADA limite di strada" />
      <category value="STR02001" symbol="2" render="true" label="BORDO_STRADA limite di strada" />
    </categories>
    <symbols>
      <symbol type="line" name="0" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleLine" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="line_color" value="153,102,51,255" type="QString" />
            <Option name="line_style" value="solid" type="QString" />
            <Option name="line_width" value="0.25" type="QString" />
            <Option name="line_width_unit" value="MM" type="QString" />
            <Option name="capstyle" value="round" type="QString" />
            <Option name="joinstyle" value="round" type="QString" />
            <Option name="use_custom_dash" value="0" type="QString" />
          </Option>
          <prop k="line_color" v="153,102,51,255" />
          <prop k="line_style" v="solid" />
          <prop k="line_width" v="0.25" />
          <prop k="line_width_unit" v="MM" />
          <prop k="capstyle" v="round" />
          <prop k="joinstyle" v="round" />
          <prop k="use_custom_dash" v="0" />
        </layer>
      </symbol>
      <symbol type="line" name="1" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleLine" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="line_color" value="255,0,0,255" type="QString" />
            <Option name="line_style" value="solid" type="QString" />
            <Option name="line_width" value="0.18" type="QString" />
            <Option name="line_width_unit" value="MM" type="QString" />
            <Option name="capstyle" value="round" type="QString" />
            <Option name="joinstyle" value="round" type="QString" />
            <Option name="use_custom_dash" value="0" type="QString" />
          </Option>
          <prop k="line_color" v="255,0,0,255" />
          <prop k="line_style" v="solid" />
          <prop k="line_width" v="0.18" />
          <prop k="line_width_unit" v="MM" />
          <prop k="capstyle" v="round" />
          <prop k="joinstyle" v="round" />
          <prop k="use_custom_dash" v="0" />
        </layer>
      </symbol>
      <symbol type="line" name="2" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleLine" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="line_color" value="255,0,0,255" type="QString" />
            <Option name="line_style" value="solid" type="QString" />
            <Option name="line_width" value="0.18" type="QString" />
            <Option name="line_width_unit" value="MM" type="QString" />
            <Option name="capstyle" value="round" type="QString" />
            <Option name="joinstyle" value="round" type="QString" />
            <Option name="use_custom_dash" value="0" type="QString" />
          </Option>
          <prop k="line_color" v="255,0,0,255" />
          <prop k="line_style" v="solid" />
          <prop k="line_width" v="0.18" />
          <prop k="line_width_unit" v="MM" />
          <prop k="capstyle" v="round" />
          <prop k="joinstyle" v="round" />
          <prop k="use_custom_dash" v="0" />
        </layer>
      </symbol>
    </symbols>
    <source-symbol>
      <symbol type="line" name="0" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleLine" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="line_color" value="153,102,51,255" type="QString" />
            <Option name="line_style" value="solid" type="QString" />
            <Option name="line_width" value="0.25" type="QString" />
            <Option name="line_width_unit" value="MM" type="QString" />
            <Option name="capstyle" value="round" type="QString" />
            <Option name="joinstyle" value="round" type="QString" />
            <Option name="use_custom_dash" value="0" type="QString" />
          </Option>
          <prop k="line_color" v="153,102,51,255" />
          <prop k="line_style" v="solid" />
          <prop k="line_width" v="0.25" />
          <prop k="line_width_unit" v="MM" />
          <prop k="capstyle" v="round" />
          <prop k="joinstyle" v="round" />
          <prop k="use_custom_dash" v="0" />
        </layer>
      </symbol>
    </source-symbol>
  </renderer-v2>
  <layerGeometryType>1</layerGeometryType>
</qgis>
